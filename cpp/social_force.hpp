// Social force pedestrian model.
//
// D. Helbing, P. Molnar, "Social force model for pedestrian dynamics", Physical Review E 51(5),
// 4282-4286, 1995. Implemented from the paper: relaxation towards the desired velocity (Eq. 2),
// repulsion from other pedestrians through the elliptical potential V(b) = V0 exp(-b/sigma)
// whose semi-minor axis b accounts for the other's step s = v_b * delta_t (Eqs. 3-4), the
// perception weight for pedestrians outside the field of view (Eq. 7), and a speed cap of 1.3
// times the desired speed (Eq. 6). Static obstacles repel through the monotonic potential
// U_aB(r) = U0 exp(-r / R) of the distance r to the closest point of obstacle B (Eq. 5; U0 = 10
// m^2/s^2, R = 0.2 m, the paper's values), unweighted by the field of view (Eq. 8 weights only
// pedestrians and attractions).
#pragma once

#include "obstacles.hpp"
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
  double wall_u0 = 10.0;            // U0_aB [m^2/s^2]
  double wall_r = 0.2;              // R [m]
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

// Velocity after one explicit Euler step of length dt (obstacles: the episode's static map).
Vec2 social_force_new_velocity(const SocialForceAgent& self, const SocialForceOther* others, int n,
                               const SocialForceParams& params, double dt,
                               const ObstacleView& obstacles = ObstacleView{});

// Sum over obstacles (each polygon or wall segment one obstacle B) of -grad U_aB at `position`:
// magnitude U0/R exp(-d/R) along the direction from the closest point of B to the agent; inside
// a solid polygon d = 0 and the force points out through the closest edge (exposed for tests).
Vec2 social_force_wall_repulsion(Vec2 position, const ObstacleView& obstacles, const SocialForceParams& params);

// Repulsive force on an agent at relative position r = r_a - r_b from a pedestrian b that moves
// with velocity v_b (exposed for tests).
Vec2 social_force_repulsion(Vec2 r, Vec2 v_b, const SocialForceParams& params);

}  // namespace socialnav
