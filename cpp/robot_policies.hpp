// Batched robot policies that need no learning: linear, ORCA and social force.
// They read observations (the same arrays a learned policy gets), never the world, and write
// actions in the world's format: (vx, vy) for a holonomic robot, (v, d theta) for a unicycle.
#pragma once

#include <cstdint>
#include <string>

#include "behaviours/builtin_params.hpp"
#include "obstacles.hpp"
#include "orca.hpp"
#include "social_force.hpp"
#include "thread_pool.hpp"

namespace socialnav {

// Observation layout: robot (B, 9) = px, py, vx, vy, radius, gx, gy, v_pref, theta;
// humans (B, N, 5) = px, py, vx, vy, radius; mask (B, N); active (B,) episodes to act for.
struct ObservationView {
  int batch;
  int humans;
  const double* robot;
  const double* human;
  const uint8_t* mask;
  const uint8_t* active;
};

struct ActionFormat {
  int kinematics;                  // 0 holonomic, 1 unicycle, 2 differential drive (world.hpp's Kinematics)
  double rotation_limit;           // [rad] per step, unicycle and differential drive
  double max_reverse_speed = 0.0;  // [m/s] differential drive: how fast it may back up
};

void linear_robot_actions(const ObservationView& obs, const ActionFormat& format, double dt, double* out);

// CrowdNav's ORCA policy: own and neighbours' radii inflated by margin + safety_space. Static
// obstacles (one episode per observation row) are avoided with RVO2's obstacle algorithm, as the
// ORCA humans do; the linear policy ignores them, as linear humans do. route_clearance >= 0: towards
// the first point of the shortest route instead of the goal (robot_actions' "_route" policies).
void orca_robot_actions(const ObservationView& obs, const ActionFormat& format, const OrcaParams& params,
                        double radius_margin, double safety_space, double dt, ThreadPool& pool, double* out,
                        const ObstacleBatchView& obstacles = ObstacleBatchView{}, double route_clearance = -1.0);

void social_force_robot_actions(const ObservationView& obs, const ActionFormat& format, const SocialForceParams& params,
                                double dt, ThreadPool& pool, double* out,
                                const ObstacleBatchView& obstacles = ObstacleBatchView{},
                                double route_clearance = -1.0);

// The robot's global plan for a learned policy that reads it (lidar_ppo's route_goal; Xie & Dames' DRL-VO
// reads a global planner's sub-goal the same way): per row of B robot rows (kRobotFeatures columns), the
// point its route around the walls alone hands the preferred-velocity law (heading_point: towards the
// route's first point, as far as the route is long), planned afresh from where it stands for its radius +
// route_clearance [m] (the cached graphs of its map); the goal itself on an open floor or with the goal in
// sight. Written into out (B, 2).
void robot_route_goals(const double* robot, int batch, const ObstacleBatchView& obstacles, double route_clearance,
                       double* out);

// The native robot policy named `policy` ("linear", "orca", "orca_route", "social_force" or
// "social_force_route"; std::invalid_argument otherwise): the ORCA one configured as the ORCA humans are
// (orca: that behaviour's values) with the robot's own safety_space [m], the social-force one with the
// humans' social-force parameters. The "_route" ones head for the first point of the shortest route
// among the obstacles (routes.hpp; Francis et al.'s "global planner + local avoidance" baseline),
// keeping route_clearance [m] from the walls where they can, beyond the radius ORCA inflates.
void robot_actions(const std::string& policy, const ObservationView& obs, const ActionFormat& format, double dt,
                   const OrcaValues& orca, double safety_space, const SocialForceParams& social_force, ThreadPool& pool,
                   double* out, const ObstacleBatchView& obstacles = ObstacleBatchView{}, double route_clearance = 0.1);

}  // namespace socialnav
