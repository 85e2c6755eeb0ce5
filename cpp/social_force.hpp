// Social force pedestrian model.
//
// D. Helbing, P. Molnar, "Social force model for pedestrian dynamics", Physical Review E 51(5),
// 4282-4286, 1995. Implemented from the paper: relaxation towards the desired velocity (Eq. 2),
// repulsion from other pedestrians through the elliptical potential V(b) = V0 exp(-b/sigma)
// whose semi-minor axis b accounts for the other's step s = v_b * delta_t (Eqs. 3-4), the
// perception weight for pedestrians outside the field of view (Eq. 7), and a speed cap of 1.3
// times the desired speed (Eq. 6). There are no walls in the protocol's scenes.
#pragma once

#include "vec2.hpp"

namespace socialnav {

struct SocialForceParams {
  double relaxation_time = 0.5;     // tau_alpha [s]
  double v0 = 2.1;                  // V0_ab [m^2/s^2]
  double sigma = 0.3;               // [m]
  double step_time = 2.0;           // delta_t used for the other's step [s]
  double fov_half_angle = 1.74533;  // phi = 100 deg [rad]
  double outside_fov_weight = 0.5;  // c
  double max_speed_factor = 1.3;    // v_max = 1.3 v0_desired
};

struct SocialForceAgent {
  Vec2 position;
  Vec2 velocity;
  Vec2 desired_velocity;  // desired speed times desired direction [m/s]
  double max_speed;       // cap on the resulting speed [m/s]
};

struct SocialForceOther {
  Vec2 position;
  Vec2 velocity;
};

// Desired velocity towards a goal: speed v_pref, easing off inside the last metre so that the
// agent stops at its goal (used for pedestrians and for the social-force robot).
inline Vec2 social_force_desired_velocity(Vec2 position, Vec2 goal, double v_pref) {
  const Vec2 to_goal = goal - position;
  const double d = norm(to_goal);
  return d > 1e-9 ? (v_pref * (d < 1.0 ? d : 1.0) / d) * to_goal : Vec2{};
}

// Velocity after one explicit Euler step of length dt.
Vec2 social_force_new_velocity(const SocialForceAgent& self, const SocialForceOther* others, int n,
                               const SocialForceParams& params, double dt);

// Repulsive force on an agent at relative position r = r_a - r_b from a pedestrian b that moves
// with velocity v_b (exposed for tests).
Vec2 social_force_repulsion(Vec2 r, Vec2 v_b, const SocialForceParams& params);

}  // namespace socialnav
