// Native episode generation; see scenario_gen.hpp. Each function names the Python code it mirrors,
// because the two must stay bit-identical.
#include "scenario_gen.hpp"

#include <cmath>
#include <initializer_list>
#include <vector>

#include "splitmix.hpp"

namespace socialnav {

namespace {

constexpr double kTwoM53 = 1.0 / 9007199254740992.0;  // 2**-53

// Draw-key streams (socialnav/scenarios/base.py).
constexpr int64_t kStreamAttributes = 1;
constexpr int64_t kStreamSide = 2;
constexpr int64_t kStreamStart = 3;
constexpr int64_t kStreamGoal = 4;

// random.py: EpisodeRandom for one episode.
class EpisodeStream {
 public:
  EpisodeStream(uint64_t salt_prefix, int64_t seed)
      : seed_hash_(fmix64((static_cast<uint64_t>(seed) ^ salt_prefix) + kGolden)) {}

  // The hash of a draw's key (EpisodeRandom.bits), shared by the draw's elements.
  static uint64_t key_hash(std::initializer_list<int64_t> key) {
    uint64_t kh = chain64(0x5EED, key.size());
    for (int64_t word : key) kh = chain64(kh, static_cast<uint64_t>(word));
    return kh;
  }

  // EpisodeRandom.random(key, size)[element]: uniform in [0, 1) with 53 bits.
  double random(uint64_t key_hash, int element) const {
    const uint64_t eh = chain64(key_hash, static_cast<uint64_t>(element));
    const uint64_t h = fmix64((seed_hash_ ^ eh) + kGolden);
    return static_cast<double>(h >> 11) * kTwoM53;
  }

 private:
  uint64_t seed_hash_;
};

struct Point {
  double x, y;
};

// _placement.py: rejection_sample's test for one candidate against m reference discs.
inline bool clear_of(Point cand, double radius, const Point* ref, const double* ref_radius, int m, double margin) {
  for (int k = 0; k < m; ++k) {
    const double min_dist = radius + ref_radius[k] + margin;
    const double min_d2 = min_dist * min_dist;
    const double dx = cand.x - ref[k].x;
    const double dy = cand.y - ref[k].y;
    const double d2 = dx * dx + dy * dy;
    if (!(d2 >= min_d2)) return false;
  }
  return true;
}

// base.py: Scenario.human_attributes.
inline void human_attributes(const ScenarioConfig& c, const EpisodeStream& rng, int j, double& radius, double& v_pref) {
  if (!c.randomize_attributes) {
    radius = c.human_radius;
    v_pref = c.human_v_pref;
    return;
  }
  const uint64_t key = EpisodeStream::key_hash({kStreamAttributes, j});
  const double u0 = rng.random(key, 0);
  const double u1 = rng.random(key, 1);
  v_pref = c.v_pref_low + (c.v_pref_high - c.v_pref_low) * u0;
  radius = c.radius_low + (c.radius_high - c.radius_low) * u1;
}

// circle.py: CircleCrossing.sample_humans.
int circle_crossing(const ScenarioConfig& c, const EpisodeStream& rng, double* start, double* goal, double* radius,
                    double* v_pref) {
  const int n = c.n_humans;
  const double r_circle = c.circle_radius;
  std::vector<Point> ref(2 + 2 * n);
  std::vector<double> ref_radius(2 + 2 * n);
  ref[0] = {0.0, -r_circle};
  ref[1] = {0.0, r_circle};
  ref_radius[0] = ref_radius[1] = c.robot_radius;
  for (int j = 0; j < n; ++j) {
    human_attributes(c, rng, j, radius[j], v_pref[j]);
    const double noise_scale = c.start_noise * v_pref[j];
    const int m = 2 + 2 * j;
    bool placed = false;
    Point cand{0.0, 0.0};
    for (int attempt = 0; attempt < c.max_attempts && !placed; ++attempt) {
      const uint64_t key = EpisodeStream::key_hash({kStreamStart, j, attempt});
      const double u0 = rng.random(key, 0);
      const double u1 = rng.random(key, 1);
      const double u2 = rng.random(key, 2);
      const double angle = u0 * (2.0 * M_PI);
      cand.x = r_circle * std::cos(angle) + (2.0 * u1 - 1.0) * noise_scale;
      cand.y = r_circle * std::sin(angle) + (2.0 * u2 - 1.0) * noise_scale;
      placed = clear_of(cand, radius[j], ref.data(), ref_radius.data(), m, c.discomfort_dist);
    }
    if (!placed) return 1 + 2 * j;
    start[2 * j] = cand.x;
    start[2 * j + 1] = cand.y;
    goal[2 * j] = -cand.x;
    goal[2 * j + 1] = -cand.y;
    ref[m] = cand;
    ref[m + 1] = {-cand.x, -cand.y};
    ref_radius[m] = ref_radius[m + 1] = radius[j];
  }
  return 0;
}

// square.py: the candidate maps of RandomPlacement, _TwoSidedTraffic and SquareCrossing.
inline Point square_candidate(const ScenarioConfig& c, double u0, double u1, double sign) {
  const double w = c.square_width;
  switch (c.kind) {
    case SCENARIO_RANDOM: return {(u0 - 0.5) * w, (u1 - 0.5) * w};
    case SCENARIO_TRAFFIC: {
      const double u[2] = {u0, u1};
      const int flow = c.flow_axis, across = 1 - c.flow_axis;
      double out[2];
      out[across] = (u[across] - 0.5) * w;
      const double depth = c.band ? c.circle_radius + (u[flow] - 0.5) * c.band_width : u[flow] * (0.5 * w);
      out[flow] = sign * depth;
      return {out[0], out[1]};
    }
    default:  // SCENARIO_SQUARE_CROSSING
      return {u0 * w * 0.5 * sign, (u1 - 0.5) * w};
  }
}

// square.py: _SquareScenario.sample_humans.
int square_family(const ScenarioConfig& c, const EpisodeStream& rng, double* start, double* goal, double* radius,
                  double* v_pref) {
  const int n = c.n_humans;
  const double r = c.circle_radius;
  std::vector<Point> starts(1 + n), goals(1 + n);
  std::vector<double> radii(1 + n);
  starts[0] = {0.0, -r};
  goals[0] = {0.0, r};
  radii[0] = c.robot_radius;
  for (int j = 0; j < n; ++j) {
    human_attributes(c, rng, j, radius[j], v_pref[j]);
    double side = 1.0;
    if (c.kind != SCENARIO_RANDOM) side = rng.random(EpisodeStream::key_hash({kStreamSide, j}), 0) > 0.5 ? -1.0 : 1.0;
    for (int which = 0; which < 2; ++which) {
      const int64_t stream = which == 0 ? kStreamStart : kStreamGoal;
      const double sign = which == 0 ? side : -side;
      Point* refs = which == 0 ? starts.data() : goals.data();
      bool placed = false;
      Point cand{0.0, 0.0};
      for (int attempt = 0; attempt < c.max_attempts && !placed; ++attempt) {
        const uint64_t key = EpisodeStream::key_hash({stream, j, attempt});
        const double u0 = rng.random(key, 0);
        const double u1 = rng.random(key, 1);
        cand = square_candidate(c, u0, u1, sign);
        placed = clear_of(cand, radius[j], refs, radii.data(), j + 1, c.discomfort_dist);
      }
      if (!placed) return (which == 0 ? 1 : 2) + 2 * j;
      refs[j + 1] = cand;
      double* out = which == 0 ? start : goal;
      out[2 * j] = cand.x;
      out[2 * j + 1] = cand.y;
    }
    radii[j + 1] = radius[j];
  }
  return 0;
}

}  // namespace

int generate_humans(const ScenarioConfig& config, int64_t seed, double* start, double* goal, double* radius,
                    double* v_pref) {
  const EpisodeStream rng(config.salt_prefix, seed);
  if (config.kind == SCENARIO_CIRCLE) return circle_crossing(config, rng, start, goal, radius, v_pref);
  return square_family(config, rng, start, goal, radius, v_pref);
}

}  // namespace socialnav
