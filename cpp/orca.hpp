// Optimal Reciprocal Collision Avoidance for one agent among neighbours.
//
// J. van den Berg, S. J. Guy, M. Lin, D. Manocha, "Reciprocal n-body collision avoidance",
// Robotics Research (ISRR 2009), Springer Tracts in Advanced Robotics 70, 2011, pp. 3-19.
// Implemented from the paper's description: one half-plane of permitted velocities per
// neighbour (Sec. 4), an incremental 2-D linear program that finds the permitted velocity
// closest to the preferred one inside the max-speed disc, and, when the half-planes leave no
// room, a 3-D linear program that minimises the largest penetration (Sec. 5.3).
// Static obstacles follow the same paper's Sec. 5 and the RVO2 library's documented behaviour:
// one half-plane per obstacle edge facing the agent (time horizon tau_obst, full responsibility),
// built before the agents' and kept hard when the 3-D program relaxes the agents' half-planes.
#pragma once

#include <vector>

#include "obstacles.hpp"
#include "vec2.hpp"

namespace socialnav {

struct OrcaParams {
  double neighbor_dist = 10.0;     // [m] neighbours farther than this are ignored
  int max_neighbors = 10;          // the closest ones are kept
  double time_horizon = 5.0;       // tau [s]
  double time_horizon_obst = 5.0;  // tau_obst [s] for static obstacles (CrowdSim's value)
};

// A directed line; the permitted half-plane lies to its left.
struct Line {
  Vec2 point;
  Vec2 direction;
};

constexpr int kMaxOrcaNeighbors = 64;
constexpr double kOrcaEpsilon = 1e-5;  // tolerance for parallel lines, as in the RVO2 library

// Reusable buffers so a solve allocates nothing once they have grown to the largest problem.
struct OrcaScratch {
  int count = 0;
  double range_sq = 0.0;
  int index[kMaxOrcaNeighbors];
  double dist_sq[kMaxOrcaNeighbors];
  std::vector<Line> lines;  // obstacle lines first, then agent lines
  std::vector<Line> projected;
  std::vector<int> obstacle_index;  // selected obstacle vertices [0, obstacle_count), by distance
  std::vector<double> obstacle_dist_sq;
  int obstacle_count = 0;
  std::vector<double> obstacle_key;  // per vertex: squared distance if selected, else +inf

  OrcaScratch() : lines(kMaxOrcaNeighbors), projected(kMaxOrcaNeighbors) {}
  void reserve_lines(int n) {
    if (static_cast<int>(lines.size()) < n) {
      lines.resize(n);
      projected.resize(n);
    }
  }

  void begin(double neighbor_dist) {
    count = 0;
    range_sq = neighbor_dist * neighbor_dist;
  }
  // Keeps the `max_neighbors` closest candidates strictly within range, sorted by distance
  // (ties keep insertion order); once full, the range shrinks to the farthest kept one.
  void offer(int candidate, double candidate_dist_sq, int max_neighbors);
};

struct OrcaAgent {
  Vec2 position;
  Vec2 velocity;
  double radius;
  double max_speed;
  Vec2 pref_velocity;
};

struct OrcaNeighbor {
  Vec2 position;
  Vec2 velocity;
  double radius;
};

// New velocity of `self` given `neighbors[0..n)` already selected and sorted by distance.
Vec2 orca_new_velocity(const OrcaAgent& self, const OrcaNeighbor* neighbors, int n, double time_horizon,
                       double time_step, OrcaScratch& scratch);

// The same with static obstacles: the obstacle edges that face the agent within
// tau_obst * max_speed + radius (RVO2's query range) are selected and sorted by distance here.
// Without obstacles (obstacles.count == 0) the result is bit-identical to the overload above.
Vec2 orca_new_velocity(const OrcaAgent& self, const ObstacleView& obstacles, double time_horizon_obst,
                       const OrcaNeighbor* neighbors, int n, double time_horizon, double time_step,
                       OrcaScratch& scratch);

// The obstacle half-planes alone (written to scratch.lines[0..count), count returned), in the order
// the solver uses them: for tests that compare them with another implementation's lines.
int orca_obstacle_lines(const OrcaAgent& self, const ObstacleView& obstacles, double time_horizon_obst,
                        OrcaScratch& scratch);

// Convenience used by tests and single-agent callers: selects neighbours (range, count) first.
Vec2 orca_new_velocity_select(const OrcaAgent& self, const OrcaNeighbor* candidates, int n, const OrcaParams& params,
                              double time_step, OrcaScratch& scratch, const ObstacleView& obstacles = ObstacleView{});

// One ORCA step of n agents among one another and the static obstacles: RVO2's computeNeighbors (every
// other agent strictly within neighbor_dist, the closest max_neighbors, sorted by distance, ties in
// index order) and computeNewVelocity for every agent; positions are not advanced. positions,
// velocities, pref_velocities, out: (n, 2); radii, max_speeds: (n,), used as given.
void orca_step_agents(int n, const double* positions, const double* velocities, const double* pref_velocities,
                      const double* radii, const double* max_speeds, const OrcaParams& params, double time_step,
                      const ObstacleView& obstacles, double* out);

// Preferred velocity of CrowdSim: the vector to the goal [per second], cut to length `speed`
// beyond `speed` metres. CrowdSim uses speed = 1 for everyone (humans keep that); the robot's ORCA
// policy passes its v_pref so that a robot faster than 1 m/s prefers its own speed.
inline Vec2 crowdsim_pref_velocity(Vec2 position, Vec2 goal, double speed = 1.0) {
  Vec2 to_goal = goal - position;
  double d = norm(to_goal);
  return d > speed ? (speed / d) * to_goal : to_goal;
}

}  // namespace socialnav
