// Native episode generation for the built-in multi-human scenarios (circle crossing and the
// square family: random, parallel and perpendicular traffic, square crossing).
//
// It computes exactly what the Python generators compute (socialnav/scenarios/{circle,square}.py):
// the same counter-based random numbers (splitmix64 finaliser chained over seed, salt, key and
// element; socialnav/scenarios/episode_random.py), the same arithmetic in the same order (no contraction:
// the build passes -ffp-contract=off) and the same libm cos/sin, so the episodes are bit-identical
// (tests/scenarios/test_native_generation.py). The Python generators stay the reference and serve
// every other scenario.
#pragma once

#include <cstdint>

namespace socialnav {

enum ScenarioKind : int {
  SCENARIO_CIRCLE = 0,
  SCENARIO_RANDOM = 1,
  SCENARIO_TRAFFIC = 2,          // parallel (flow_axis 1) and perpendicular (flow_axis 0) traffic
  SCENARIO_SQUARE_CROSSING = 3,  // CrowdNav's square crossing
};

struct ScenarioConfig {
  int kind = SCENARIO_CIRCLE;
  int n_humans = 5;
  uint64_t salt_prefix = 0;  // fmix64(salt_hash(name) + golden): the per-scenario hash prefix
  double robot_radius = 0.3;
  double robot_v_pref = 1.0;
  double human_radius = 0.3;
  double human_v_pref = 1.0;
  bool randomize_attributes = false;
  double v_pref_low = 0.5, v_pref_high = 1.5;
  double radius_low = 0.3, radius_high = 0.5;
  double discomfort_dist = 0.2;
  double circle_radius = 4.0;
  int max_attempts = 1000;
  double start_noise = 0.5;    // circle crossing
  double square_width = 12.0;  // square family
  int flow_axis = 1;           // traffic
  bool band = false;           // traffic: 'band' area instead of 'half_square'
  double band_width = 2.0;     // traffic
};

// Humans of one episode. Outputs: start, goal (n_humans × 2), radius, v_pref (n_humans).
// Returns 0 on success, or 1 + 2·j (start of human j) / 2 + 2·j (goal of human j) for the first
// quantity that found no clear position within max_attempts.
int generate_humans(const ScenarioConfig& config, int64_t seed, double* start, double* goal, double* radius,
                    double* v_pref);

}  // namespace socialnav
