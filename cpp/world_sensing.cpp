// The World's side of the robot's perception (sensing.hpp): which humans observe() reports and how, the
// lidar scan, and the record of past states that latency reads. The world's state itself stays exact.
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "observation_layout.hpp"
#include "world.hpp"

namespace socialnav {

namespace {

// Stream numbers of the counter-based draws (sensing_uniform / sensing_normal).
constexpr uint64_t kDropoutStream = 1;
constexpr uint64_t kPositionStream = 2;  // + 0 / 1: x / y
constexpr uint64_t kVelocityStream = 4;  // + 0 / 1: x / y
constexpr uint64_t kLidarStream = 6;

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument("sensing: " + what);
}

}  // namespace

void World::set_sensing(const SensingConfig& s, const int64_t* episode_seed) {
  require(s.range > 0.0, "range must be > 0 m, got " + std::to_string(s.range));
  require(s.fov > 0.0 && s.fov <= 2.0 * M_PI, "fov must be in (0, 2 pi], got " + std::to_string(s.fov));
  require(s.position_noise >= 0.0 && std::isfinite(s.position_noise), "position_noise must be >= 0");
  require(s.velocity_noise >= 0.0 && std::isfinite(s.velocity_noise), "velocity_noise must be >= 0");
  require(s.dropout >= 0.0 && s.dropout <= 1.0, "dropout must be in [0, 1], got " + std::to_string(s.dropout));
  require(s.latency >= 0 && s.latency <= 1000, "latency must be in [0, 1000] steps");
  require(s.lidar_beams >= 0 && s.lidar_beams <= 100000, "lidar_beams must be in [0, 100000]");
  require(s.lidar_fov > 0.0 && s.lidar_fov <= 2.0 * M_PI, "lidar_fov must be in (0, 2 pi]");
  require(s.lidar_range > 0.0 && std::isfinite(s.lidar_range), "lidar_range must be finite and > 0 m");
  require(s.lidar_noise >= 0.0 && std::isfinite(s.lidar_noise), "lidar_noise must be >= 0");
  require(episode_seed != nullptr ||
              (s.position_noise == 0.0 && s.velocity_noise == 0.0 && s.dropout == 0.0 && s.lidar_noise == 0.0),
          "noise and dropout need the episodes' seeds");
  sensing_ = s;
  detections_exact_ = s.exact_detections();
  episode_seed_ = episode_seed;
  const std::vector<double> angles = lidar_beam_angles(s.lidar_beams, s.lidar_fov);
  beam_cos_.resize(angles.size());
  beam_sin_.resize(angles.size());
  for (size_t i = 0; i < angles.size(); ++i) {
    beam_cos_[i] = std::cos(angles[i]);
    beam_sin_[i] = std::sin(angles[i]);
  }
  const size_t stride = 4 * static_cast<size_t>(config_.agents) + 1;
  sensed_history_.assign(s.latency > 0 ? static_cast<size_t>(config_.batch) * (s.latency + 1) * stride : 0, 0.0);
}

// Entry (step mod latency + 1) of slot b: positions (A, 2), velocities (A, 2), the robot's theta.
void World::remember_for_sensing(int b, int step) {
  const int A = config_.agents;
  const size_t stride = 4 * static_cast<size_t>(A) + 1;
  const int slots = sensing_.latency + 1;
  double* entry = sensed_history_.data() + (static_cast<size_t>(b) * slots + step % slots) * stride;
  const double* pos = buf_.position + static_cast<size_t>(b) * A * 2;
  const double* vel = buf_.velocity + static_cast<size_t>(b) * A * 2;
  for (int k = 0; k < 2 * A; ++k) entry[k] = pos[k];
  for (int k = 0; k < 2 * A; ++k) entry[2 * A + k] = vel[k];
  entry[4 * A] = buf_.theta[b];
}

std::vector<double> World::sensing_state(int b) const {
  if (b < 0 || b >= config_.batch) throw std::invalid_argument("slot " + std::to_string(b) + " out of range");
  if (sensing_.latency == 0) return {};
  const size_t size = static_cast<size_t>(sensing_.latency + 1) * (4 * static_cast<size_t>(config_.agents) + 1);
  const double* first = sensed_history_.data() + static_cast<size_t>(b) * size;
  return std::vector<double>(first, first + size);
}

void World::set_sensing_state(int b, const double* state, size_t size) {
  if (b < 0 || b >= config_.batch) throw std::invalid_argument("slot " + std::to_string(b) + " out of range");
  const size_t expected =
      sensing_.latency == 0 ? 0
                            : static_cast<size_t>(sensing_.latency + 1) * (4 * static_cast<size_t>(config_.agents) + 1);
  if (size != expected)
    throw std::invalid_argument("sensing state of slot " + std::to_string(b) + ": " + std::to_string(size) +
                                " values, expected " + std::to_string(expected));
  std::copy(state, state + size, sensed_history_.data() + static_cast<size_t>(b) * expected);
}

void World::sense_humans(int b, const ObservationBuffers& o, int64_t row) const {
  const int A = config_.agents;
  const int N = A - 1;
  const int steps = buf_.steps[b];
  // The state the detections are taken from: `latency` steps ago, or the episode's start before then.
  int source_step = steps;
  const double* pos = buf_.position + static_cast<size_t>(b) * A * 2;
  const double* vel = buf_.velocity + static_cast<size_t>(b) * A * 2;
  double theta = buf_.theta[b];
  if (sensing_.latency > 0 && steps > 0) {
    source_step = steps > sensing_.latency ? steps - sensing_.latency : 0;
    const int slots = sensing_.latency + 1;
    const size_t stride = 4 * static_cast<size_t>(A) + 1;
    const double* entry = sensed_history_.data() + (static_cast<size_t>(b) * slots + source_step % slots) * stride;
    pos = entry;
    vel = entry + 2 * A;
    theta = entry[4 * A];
  }
  const double* radius = buf_.radius + static_cast<size_t>(b) * A;
  const uint8_t* mask = buf_.mask + static_cast<size_t>(b) * A;
  const double* goal = buf_.goal + static_cast<size_t>(b) * A * 2;
  const Vec2 eye{pos[0], pos[1]};
  const double heading =
      sensor_heading(config_.kinematics != kHolonomic, theta, Vec2{vel[0], vel[1]}, eye, Vec2{goal[0], goal[1]});
  const ObstacleView walls = sensing_.occlusion_walls ? obstacles(b) : ObstacleView{};
  thread_local std::vector<uint8_t> skip;
  skip.assign(static_cast<size_t>(N), 0);
  for (int i = 1; i < A; ++i) skip[i - 1] = mask[i] == 0;
  const int64_t seed = episode_seed_ ? episode_seed_[b] : 0;
  const bool occlusion = sensing_.occlusion_walls || sensing_.occlusion_humans;
  for (int i = 1; i < A; ++i) {
    const size_t slot = static_cast<size_t>(row) * N + (i - 1);
    double* h = o.humans + slot * kHumanFeatures;
    if (!mask[i]) continue;  // observe_one wrote an empty slot already
    const Vec2 c{pos[2 * i], pos[2 * i + 1]};
    const Vec2 to = c - eye;
    bool seen = abs_sq(to) <= sensing_.range * sensing_.range;
    if (seen && sensing_.fov < 2.0 * M_PI)
      seen = std::abs(std::remainder(std::atan2(to.y, to.x) - heading, 2.0 * M_PI)) <= 0.5 * sensing_.fov;
    if (seen && occlusion) {
      skip[i - 1] = 1;  // a disc does not hide itself
      seen =
          disc_in_sight(eye, c, radius[i], walls, pos + 2, radius + 1, skip.data(), sensing_.occlusion_humans ? N : 0);
      skip[i - 1] = 0;
    }
    if (seen && sensing_.dropout > 0.0)
      seen = sensing_uniform(seed, source_step, i, kDropoutStream) >= sensing_.dropout;
    o.human_mask[slot] = seen;
    if (!seen) {
      h[0] = h[1] = h[2] = h[3] = h[4] = 0.0;
      continue;
    }
    h[0] = c.x;
    h[1] = c.y;
    h[2] = vel[2 * i];
    h[3] = vel[2 * i + 1];
    h[4] = radius[i];
    if (sensing_.position_noise > 0.0) {
      h[0] += sensing_.position_noise * sensing_normal(seed, source_step, i, kPositionStream);
      h[1] += sensing_.position_noise * sensing_normal(seed, source_step, i, kPositionStream + 1);
    }
    if (sensing_.velocity_noise > 0.0) {
      h[2] += sensing_.velocity_noise * sensing_normal(seed, source_step, i, kVelocityStream);
      h[3] += sensing_.velocity_noise * sensing_normal(seed, source_step, i, kVelocityStream + 1);
    }
  }
}

void World::scan_lidar(int b, float* out) const {
  const int A = config_.agents;
  const int n = sensing_.lidar_beams;
  const double* pos = buf_.position + static_cast<size_t>(b) * A * 2;
  const double* vel = buf_.velocity + static_cast<size_t>(b) * A * 2;
  const double* goal = buf_.goal + static_cast<size_t>(b) * A * 2;
  const uint8_t* mask = buf_.mask + static_cast<size_t>(b) * A;
  const Vec2 eye{pos[0], pos[1]};
  const double heading = sensor_heading(config_.kinematics != kHolonomic, buf_.theta[b], Vec2{vel[0], vel[1]}, eye,
                                        Vec2{goal[0], goal[1]});
  thread_local std::vector<double> ranges;
  thread_local std::vector<uint8_t> skip;
  ranges.resize(static_cast<size_t>(n));
  skip.resize(static_cast<size_t>(A - 1));
  for (int i = 1; i < A; ++i) skip[i - 1] = mask[i] == 0;
  lidar_scan(eye, heading, beam_cos_.data(), beam_sin_.data(), n, sensing_.lidar_range, obstacles(b), pos + 2,
             buf_.radius + static_cast<size_t>(b) * A + 1, skip.data(), A - 1, ranges.data(), sensing_.lidar_fov);
  const double sigma = sensing_.lidar_noise;
  const double range = sensing_.lidar_range;
  if (sigma > 0.0) {
    const int64_t seed = episode_seed_ ? episode_seed_[b] : 0;
    const int steps = buf_.steps[b];
    for (int i = 0; i < n; ++i) {
      // A beam that hit nothing reads the maximum range, as a lidar reports "no return".
      if (ranges[i] < range)
        ranges[i] = std::clamp(ranges[i] + sigma * sensing_normal(seed, steps, i, kLidarStream), 0.0, range);
    }
  }
  store_ranges(ranges.data(), n, out);
}

}  // namespace socialnav
