#include "robot_policies.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

#include "observation_layout.hpp"
#include "routes.hpp"

namespace socialnav {

namespace {

// Turns a velocity command into the action format. A unicycle turns towards the commanded
// velocity as far as its rotation limit allows and drives at the commanded speed (CrowdSim's rule). A
// differential drive turns the same way but drives only the command's component along its heading,
// |u| cos(error), so that it does not run off sideways while it turns; one that may reverse aligns whichever
// of its front and back is nearer the command and backs up where the back is (docs/kinematics.md).
void write_action(const ActionFormat& format, double theta, Vec2 v, double* out) {
  if (format.kinematics == 0) {
    out[0] = v.x;
    out[1] = v.y;
    return;
  }
  const double speed = norm(v);
  double error = 0.0;
  if (speed > 1e-12) {
    const double a = std::atan2(v.y, v.x) - theta;
    error = std::atan2(std::sin(a), std::cos(a));
  }
  double drive = speed;
  if (format.kinematics == 2) {
    drive = speed * std::cos(error);
    if (format.max_reverse_speed > 0.0 && std::abs(error) > 0.5 * M_PI) {
      error = error > 0.0 ? error - M_PI : error + M_PI;  // the back faces the command
      drive = std::max(drive, -format.max_reverse_speed);
    } else {
      drive = std::max(drive, 0.0);
    }
  }
  out[0] = drive;
  out[1] = std::min(std::max(error, -format.rotation_limit), format.rotation_limit);
}

struct RobotRow {
  Vec2 p, v, g;
  double radius, v_pref, theta;
};

inline RobotRow robot_row(const ObservationView& obs, int b) {
  const double* r = obs.robot + static_cast<size_t>(b) * kRobotFeatures;
  return RobotRow{{r[0], r[1]}, {r[2], r[3]}, {r[5], r[6]}, r[4], r[7], r[8]};
}

// People slower than this [m/s] are standing: the route-following policies plan around them.
constexpr double kStandingSpeed = 0.1;

// Where the robot heads: its goal, or among obstacles with routes (route_clearance >= 0) the first point
// of the shortest route from where it stands (routes.hpp) around the walls and the people standing still
// (the global planner's obstacle layer: a standing group or a person waiting at a corridor's end blocks a
// passage as a wall does), planned afresh each step so that it needs no memory between calls, headed for as
// a routed human heads for its route (heading_point).
// `radius`: the robot's radius as its local planner inflates it; `margin`: what that planner adds to each
// person's radius (ORCA's radius margin and safety space), which the route keeps too.
Vec2 robot_target(const ObstacleView& walls, const ObservationView& obs, int b, Vec2 p, Vec2 goal, double radius,
                  double margin, double route_clearance) {
  if (route_clearance < 0.0 || walls.count == 0) return goal;
  thread_local Route route;
  thread_local std::vector<Vec2> centres;
  thread_local std::vector<double> radii;
  centres.clear();
  radii.clear();
  const double* h = obs.human + static_cast<size_t>(b) * obs.humans * kHumanFeatures;
  const uint8_t* m = obs.mask + static_cast<size_t>(b) * obs.humans;
  for (int j = 0; j < obs.humans; ++j) {
    const double* hj = h + kHumanFeatures * j;
    if (!m[j] || hj[2] * hj[2] + hj[3] * hj[3] >= kStandingSpeed * kStandingSpeed) continue;
    centres.push_back(Vec2{hj[0], hj[1]});
    radii.push_back(hj[4] + margin);
  }
  plan_route_around(walls, centres.data(), radii.data(), static_cast<int>(centres.size()), p, goal, radius,
                    route_clearance, route);
  return heading_point(route, 0, p, goal);
}

}  // namespace

void linear_robot_actions(const ObservationView& obs, const ActionFormat& format, double dt, double* out) {
  for (int b = 0; b < obs.batch; ++b) {
    out[2 * b] = out[2 * b + 1] = 0.0;
    if (!obs.active[b]) continue;
    const RobotRow r = robot_row(obs, b);
    write_action(format, r.theta, straight_to_goal_velocity(r.p, r.g, r.v_pref, dt), out + 2 * b);
  }
}

void orca_robot_actions(const ObservationView& obs, const ActionFormat& format, const OrcaParams& params,
                        double radius_margin, double safety_space, double dt, ThreadPool& pool, double* out,
                        const ObstacleBatchView& obstacles, double route_clearance) {
  const int N = obs.humans;
  pool.parallel_for(obs.batch, [&](int begin, int end, int) {
    // One per thread, kept between calls: its line buffers grow once to the largest problem.
    thread_local OrcaScratch scratch;
    OrcaNeighbor nb[kMaxOrcaNeighbors];
    for (int b = begin; b < end; ++b) {
      out[2 * b] = out[2 * b + 1] = 0.0;
      if (!obs.active[b]) continue;
      const RobotRow r = robot_row(obs, b);
      const double* h = obs.human + static_cast<size_t>(b) * N * kHumanFeatures;
      const uint8_t* m = obs.mask + static_cast<size_t>(b) * N;
      scratch.begin(params.neighbor_dist);
      for (int j = 0; j < N; ++j)
        if (m[j])
          scratch.offer(j, abs_sq(Vec2{h[kHumanFeatures * j], h[kHumanFeatures * j + 1]} - r.p), params.max_neighbors);
      const double margin = radius_margin + safety_space;
      for (int k = 0; k < scratch.count; ++k) {
        const double* hj = h + kHumanFeatures * scratch.index[k];
        nb[k] = OrcaNeighbor{{hj[0], hj[1]}, {hj[2], hj[3]}, hj[4] + margin};
      }
      const Vec2 target =
          robot_target(obstacles.episode(b), obs, b, r.p, r.g, r.radius + margin, margin, route_clearance);
      const OrcaAgent self{r.p, r.v, r.radius + margin, r.v_pref, crowdsim_pref_velocity(r.p, target, r.v_pref)};
      const Vec2 v = orca_new_velocity(self, obstacles.orca_episode(b), params.time_horizon_obst, nb, scratch.count,
                                       params.time_horizon, dt, scratch);
      write_action(format, r.theta, v, out + 2 * b);
    }
  });
}

void social_force_robot_actions(const ObservationView& obs, const ActionFormat& format, const SocialForceParams& params,
                                double dt, ThreadPool& pool, double* out, const ObstacleBatchView& obstacles,
                                double route_clearance) {
  const int N = obs.humans;
  pool.parallel_for(obs.batch, [&](int begin, int end, int) {
    // Grows once per thread to the largest crowd seen; no allocation in steady state.
    thread_local std::vector<SocialForceOther> others;
    if (others.size() < static_cast<size_t>(N)) others.resize(static_cast<size_t>(N));
    for (int b = begin; b < end; ++b) {
      out[2 * b] = out[2 * b + 1] = 0.0;
      if (!obs.active[b]) continue;
      const RobotRow r = robot_row(obs, b);
      const double* h = obs.human + static_cast<size_t>(b) * N * kHumanFeatures;
      const uint8_t* m = obs.mask + static_cast<size_t>(b) * N;
      int n = 0;
      for (int j = 0; j < N; ++j)
        if (m[j])
          others[n++] = SocialForceOther{{h[kHumanFeatures * j], h[kHumanFeatures * j + 1]},
                                         {h[kHumanFeatures * j + 2], h[kHumanFeatures * j + 3]}};
      // The robot never exceeds its own v_pref, unlike a pedestrian's 1.3x margin.
      const Vec2 target = robot_target(obstacles.episode(b), obs, b, r.p, r.g, r.radius, 0.0, route_clearance);
      const SocialForceAgent self{r.p, r.v, social_force_desired_velocity(r.p, target, r.v_pref), r.v_pref};
      write_action(format, r.theta, social_force_new_velocity(self, others.data(), n, params, dt, obstacles.episode(b)),
                   out + 2 * b);
    }
  });
}

void robot_route_goals(const double* robot, int batch, const ObstacleBatchView& obstacles, double route_clearance,
                       double* out) {
  thread_local Route route;
  for (int b = 0; b < batch; ++b) {
    const double* r = robot + static_cast<size_t>(b) * kRobotFeatures;
    const Vec2 p{r[0], r[1]}, goal{r[5], r[6]};
    Vec2 target = goal;
    const ObstacleView walls = obstacles.episode(b);
    if (walls.count > 0) {
      plan_route(walls, p, goal, r[4], route_clearance, route);
      target = heading_point(route, 0, p, goal);
    }
    out[2 * b] = target.x;
    out[2 * b + 1] = target.y;
  }
}

void robot_actions(const std::string& policy, const ObservationView& obs, const ActionFormat& format, double dt,
                   const OrcaValues& orca, double safety_space, const SocialForceParams& social_force, ThreadPool& pool,
                   double* out, const ObstacleBatchView& obstacles, double route_clearance) {
  if (policy == "linear")
    linear_robot_actions(obs, format, dt, out);
  else if (policy == "orca")
    orca_robot_actions(obs, format, orca.solver, orca.radius_margin, safety_space, dt, pool, out, obstacles);
  else if (policy == "orca_route")
    orca_robot_actions(obs, format, orca.solver, orca.radius_margin, safety_space, dt, pool, out, obstacles,
                       route_clearance);
  else if (policy == "social_force")
    social_force_robot_actions(obs, format, social_force, dt, pool, out, obstacles);
  else if (policy == "social_force_route")
    social_force_robot_actions(obs, format, social_force, dt, pool, out, obstacles, route_clearance);
  else
    throw std::invalid_argument("unknown native robot policy '" + policy +
                                "'; valid: linear, orca, orca_route, social_force, social_force_route");
}

}  // namespace socialnav
