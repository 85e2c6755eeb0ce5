// What the robot perceives (docs/perception.md): which humans it detects (sensor range, field of view,
// occlusion by walls and by other humans), how wrong and how late the detections are (Gaussian noise,
// dropout, latency), and a 2-D lidar. Everything here is the robot's view only: collisions, rewards and
// metrics read the world's ground truth.
//
// Random draws are counter-based (a hash of the episode's seed, the step, the agent or beam and a stream
// number), so a run is deterministic for its seeds and identical for any thread count or batch layout.
#pragma once

#include <cmath>
#include <cstdint>
#include <vector>

#include "obstacles.hpp"
#include "vec2.hpp"

namespace socialnav {

struct SensingConfig {
  double range = INFINITY;        // a human whose centre is farther is not detected [m]
  double fov = 2.0 * M_PI;        // detection sector about the sensor's heading [rad]
  bool occlusion_walls = false;   // a human no point of whose disc is in sight past the walls is not detected
  bool occlusion_humans = false;  // ... nor one hidden behind other humans' discs
  double position_noise = 0.0;    // std of the Gaussian added to each detected position coordinate [m]
  double velocity_noise = 0.0;    // std of the Gaussian added to each detected velocity coordinate [m/s]
  double dropout = 0.0;           // probability that a detectable human is missed in a step
  int latency = 0;                // the detections are of the world `latency` steps ago
  int lidar_beams = 0;            // 0: no lidar
  double lidar_fov = 2.0 * M_PI;  // [rad] about the sensor's heading
  double lidar_range = 10.0;      // [m]: the reading of a beam that hits nothing
  double lidar_noise = 0.0;       // std of the Gaussian added to each return [m]

  // Whether the detections are the world's exact state (the lidar aside).
  bool exact_detections() const {
    return std::isinf(range) && fov >= 2.0 * M_PI && !occlusion_walls && !occlusion_humans && position_noise == 0.0 &&
           velocity_noise == 0.0 && dropout == 0.0 && latency == 0;
  }
};

// The beam angles relative to the heading: over a full circle, -pi + i * 2 pi / n (no beam twice); over a
// sector, -fov/2 + i * fov / (n - 1) (both edges).
std::vector<double> lidar_beam_angles(int beams, double fov);

// The heading sensors are mounted along: the unicycle's theta; for a holonomic robot its direction of
// travel, or the direction to its goal while it stands (CrowdNav++'s rule for a holonomic robot's view).
double sensor_heading(bool unicycle, double theta, Vec2 velocity, Vec2 position, Vec2 goal);

// Whether some point of the disc (centre, radius) is in sight from `eye`: a straight segment from the eye
// reaches it without crossing a wall edge of `walls` or a disc of `others` (n_others discs at
// other_pos[2 * k], other_radius[k]; entries with skip[k] != 0 are ignored). Exact up to grazing rays: the
// disc's angular interval is cut at every angle where what blocks a ray can change (edge ends, the
// occluders' tangents, where an occluder crosses the disc's outline) and one ray per piece is tested.
bool disc_in_sight(Vec2 eye, Vec2 centre, double radius, const ObstacleView& walls, const double* other_pos,
                   const double* other_radius, const uint8_t* skip, int n_others);

// One scan: out[i] is the distance from `eye` along beam i (heading + angle[i]) to the nearest wall edge or
// disc (n_discs discs; entries with skip[k] != 0 ignored), `range` where none is nearer. beam_cos/sin are the
// n beams' directions relative to the heading, laid out by lidar_beam_angles(n, fov). A disc that contains
// the eye gives 0 on every beam.
void lidar_scan(Vec2 eye, double heading, const double* beam_cos, const double* beam_sin, int n, double range,
                const ObstacleView& walls, const double* disc_pos, const double* disc_radius, const uint8_t* skip,
                int n_discs, double* out, double fov);

// out[i] = ranges[i] as float32, for i < n (the observation's layout).
void store_ranges(const double* ranges, int n, float* out);

// Counter-based draws: uniform in [0, 1) and standard normal, for (seed, step, index, stream).
double sensing_uniform(int64_t seed, int64_t step, int64_t index, uint64_t stream);
double sensing_normal(int64_t seed, int64_t step, int64_t index, uint64_t stream);

}  // namespace socialnav
