// The batched crowd world: B episodes x (1 robot + N humans) advanced in lockstep.
//
// State lives in caller-owned, C-contiguous arrays (structure of arrays, SI units); the world
// keeps raw pointers to them and writes in place, so the Python side reads the state without
// copies and resets finished episodes by writing into the same arrays. Semantics follow
// CrowdSim (Chen et al., ICRA 2019) as described in docs/simulator.md.
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "behaviour.hpp"
#include "obstacles.hpp"
#include "routes.hpp"
#include "scenario_gen.hpp"
#include "sensing.hpp"
#include "thread_pool.hpp"

namespace socialnav {

enum Status : int8_t {
  kIdle = -1,  // slot holds no episode
  kRunning = 0,
  kSuccess = 1,
  kCollision = 2,
  kTimeout = 3,
  kContinuing = 4,  // robot succeeded and is parked; humans still walking (M_III)
};

// Why a collision ended an episode (collision_kind buffers).
enum CollisionKind : int8_t { kNoCollision = 0, kHumanCollision = 1, kObstacleCollision = 2 };

// kDiffDrive: a differential-drive robot, whose actions are the unicycle's (v, d theta) commands, reached
// within acceleration limits from the (v, omega) it drove in the last step (World::diff_drive_velocity).
enum Kinematics : int { kHolonomic = 0, kUnicycle = 1, kDiffDrive = 2 };

struct WorldConfig {
  int batch = 0;
  int agents = 0;  // 1 robot + N human slots
  double dt = 0.25;
  double time_limit = 25.0;
  // The humans' registered behaviour (behaviour.hpp) and its parameter values in declared order
  // (empty: its defaults); "" for velocities the caller gives every step (World::give_human_velocities).
  std::string human_behaviour = "orca";
  std::vector<double> human_params;
  bool robot_visible = false;
  int kinematics = kHolonomic;
  double rotation_limit = 0.7853981633974483;  // |d theta| per step for the unicycle and diff drive [rad]
  // The differential drive's limits: |dv/dt| [m/s^2], |d omega/dt| [rad/s^2], and the fastest it backs up.
  double max_linear_accel = 2.5;
  double max_angular_accel = 3.2;
  double max_reverse_speed = 0.0;  // [m/s]
  bool crowdsim_compat = false;
  double discomfort_dist = 0.2;
  double success_reward = 1.0;
  double collision_penalty = -0.25;
  double discomfort_penalty_factor = 0.5;
  bool continue_after_success = false;
  double continuation_cap = 100.0;  // [s] since the start of the episode
  int history_len = 0;              // samples recorded per episode; 0 disables recording
  int threads = 1;
  int max_obstacle_vertices = 0;              // bound on one episode's obstacle vertices (set_obstacles checks)
  double obstacle_collision_penalty = -0.25;  // reward when the robot touches an obstacle
  bool obstacle_collision_ends = true;        // touching an obstacle ends the episode (as a human)
  // The humans among obstacles follow shortest routes to their goals (routes.hpp), keeping
  // route_clearance [m] from the walls where they can; false: they head straight for their goals.
  bool human_routes = false;
  double route_clearance = 0.2;
};

struct WorldBuffers {
  double* position;        // (B, A, 2)
  double* velocity;        // (B, A, 2) velocity applied in the last step
  double* goal;            // (B, A, 2)
  double* radius;          // (B, A)
  double* v_pref;          // (B, A)
  uint8_t* mask;           // (B, A) agent slot in use (robot always 1)
  double* theta;           // (B,) robot heading
  int32_t* steps;          // (B,) steps taken in the episode
  int8_t* status;          // (B,) Status
  double* reward;          // (B,) reward of the last step
  double* dmin;            // (B,) minimum swept clearance of the last step
  uint8_t* done;           // (B,) episode finished in the last step
  int32_t* overlaps;       // (B,) human-human overlap count so far
  double* arrival;         // (B, A) first arrival time at the goal, NaN before
  int32_t* end_step;       // (B,) step at which the robot's outcome was decided, -1 before
  double* hist_position;   // (B, T, A, 2) or null
  double* hist_velocity;   // (B, T, A, 2) or null
  double* hist_dmin;       // (B, T) or null (entry k: clearance during step k; entry 0 unused)
  int8_t* collision_kind;  // (B,) CollisionKind of the episode's collision, or null
};

// The policies' observation arrays (see World::observe).
struct ObservationBuffers {
  double* robot;           // (B, kRobotFeatures) (observation_layout.hpp)
  double* humans;          // (B, N, kHumanFeatures)
  uint8_t* human_mask;     // (B, N)
  uint8_t* active;         // (B,)
  double* time;            // (B,)
  float* lidar = nullptr;  // (B, beams) with a lidar (World::set_sensing), else null
};

// What one step reports per slot, for the caller (each (B,), written for every slot).
struct StepOutputs {
  double* reward;                // the step's reward (0 for idle slots)
  uint8_t* terminated;           // the episode ended by success or collision in this step
  uint8_t* truncated;            // the episode ended by the time limit in this step
  int8_t* outcome;               // its final Status where an episode ended in this step, kRunning elsewhere
  double* final_dmin;            // dmin where an episode ended in this step, NaN elsewhere
  int64_t* final_episode;        // episode_index where an episode ended in this step, -1 elsewhere
  int8_t* collision_kind;        // CollisionKind where an episode ended in this step, 0 elsewhere (or null)
  const int64_t* episode_index;  // input: the slots' episode indices
};

class World {
 public:
  // `pool`: the worker pool to run on (config.threads threads; not owned, it must outlive the world),
  // or null for a pool of the world's own.
  World(const WorldConfig& config, const WorldBuffers& buffers, ThreadPool* pool = nullptr);

  const WorldConfig& config() const { return config_; }
  const WorldBuffers& buffers() const { return buf_; }

  // Advances every running episode by one step; actions (B, 2) are (vx, vy) for a holonomic
  // robot or (v, d theta) for a unicycle. Throws std::invalid_argument on non-finite actions.
  // With `out`, also writes the per-slot report (same parallel pass: no Python over B afterwards).
  // Returns the number of episodes that ended in this step (done == 1).
  int step(const double* actions, const StepOutputs* out = nullptr);

  // Sets the static obstacles of slot b (flat polygons, see obstacles.hpp); they stay until the next
  // call for that slot (refills keep them). Throws std::invalid_argument when the map has more than
  // config.max_obstacle_vertices vertices or a malformed polygon. n_polygons == 0 clears them.
  void set_obstacles(int b, const double* vertices, const int64_t* offsets, int n_polygons);
  ObstacleView obstacles(int b) const {
    const PreparedObstacles* map = slot_obstacles_[b].get();
    return map ? map->view() : ObstacleView{};
  }
  // Slot b's obstacles as ORCA sees them (RVO2's split edges and tree, OrcaObstacles).
  ObstacleView orca_obstacles(int b) const {
    const PreparedObstacles* map = slot_obstacles_[b].get();
    return map ? map->orca_view() : ObstacleView{};
  }

  // With human_routes: the route state of slot b's humans (what RouteFollower holds that decides where they
  // head), as doubles, so that a run saved mid-episode resumes as it went on (train/ppo/worlds.py); empty
  // without routes. set_route_state puts back what route_state gave; throws std::invalid_argument on a
  // malformed state.
  std::vector<double> route_state(int b) const;
  void set_route_state(int b, const double* state, size_t size);

  // The robot's perception (sensing.hpp): observe() then gives the humans as the robot detects them and,
  // with lidar beams, a scan; `episode_seed` (B,) keys the noise and dropout draws (caller-owned, it must
  // outlive the world; the World's episode_seed array). Without a call, observations are exact. Throws
  // std::invalid_argument on a setting out of range.
  void set_sensing(const SensingConfig& sensing, const int64_t* episode_seed);
  const SensingConfig& sensing() const { return sensing_; }
  // With latency: slot b's last latency + 1 world states (what delayed detections are taken from), so that
  // a run saved mid-episode resumes as it went on; empty without latency. set_sensing_state puts it back.
  std::vector<double> sensing_state(int b) const;
  // A differential-drive robot's (v [m/s], omega [rad/s]) of slot b's last step. Every episode starts at
  // rest: with new_at_rest, a slot whose episode has not stepped yet reads (0, 0) whatever it drove before
  // (false: what it last drove, a finished episode's until the slot steps). Restored with set_robot_twist.
  Vec2 robot_twist(int b, bool new_at_rest = true) const;
  void set_robot_twist(int b, double v, double omega);
  void set_sensing_state(int b, const double* state, size_t size);

  // With human_behaviour "": the humans' velocities (B, A, 2) of the next step (or preview), written by
  // the caller before each call (a behaviour written in Python); entries of robots and empty slots are
  // not read. The array must outlive the world or the next call.
  void give_human_velocities(const double* velocity) { given_velocity_ = velocity; }
  bool takes_given_velocities() const { return !behaviour_; }

  // The humans' exact next states (B, N, 5: px, py, vx, vy, radius) without advancing anything:
  // the "oracle" information some policies are given. Human motion depends on the robot only
  // through its current state (when visible), never on the robot's next action.
  void preview_humans(double* out);

  // The policies' observation of every slot (socialnav/sim/observation.py, build_observation):
  // robot (B, 9) px, py, vx, vy, radius, gx, gy, v_pref, theta; humans (B, N, 5) px, py, vx, vy,
  // radius, zero in empty slots; human_mask (B, N); active (B,) running; time (B,) steps * dt.
  void observe(const ObservationBuffers& obs);

  // Generates episode i of `seeds` (a built-in scenario, scenario_gen.hpp) into slot slots[i] and
  // starts it, as socialnav/sim/world.py's World._load does with a generated EpisodeBatch, in the
  // worker threads. failure[i] is generate_humans' code (> 0), or < 0 where the slot's obstacles cover an
  // agent's start (-(1 + 2a)) or goal (-(2 + 2a)), agent 0 being the robot; a failed slot is left idle.
  void load_generated(const ScenarioConfig& scenario, const int64_t* slots, const int64_t* seeds, int k,
                      int32_t* failure);

  // Refills the slots whose episode ended in the last step (done == 1), in slot order, with the
  // episodes indices[0..count) (seeds[j] the seed of indices[j]; fewer finished slots use a prefix),
  // through load_generated; finished slots beyond `count` are left idle with episode index -1. This is
  // socialnav/sim/world.py's World._fill_native over done.nonzero(), without the Python. Writes
  // episode_index/episode_seed (B,) of the refilled slots; failure[j] is load_generated's code for the
  // j-th. Returns the number of failed generations. With `obs`, also writes the observation of every
  // slot afterwards (observe's result); with `final_obs` (rows: the finished slots in slot order), the
  // finished slots' observation before their refill; both in the same parallel pass.
  int refill_done(const ScenarioConfig& scenario, const int64_t* indices, const int64_t* seeds, int count,
                  int64_t* episode_index, int64_t* episode_seed, int32_t* failure,
                  const ObservationBuffers* obs = nullptr, const ObservationBuffers* final_obs = nullptr);

 private:
  // targets_ready: route_targets(b) ran for this step (World::step runs it ahead, a block of slots at a time).
  void step_episode(int b, const double* actions, int worker, bool targets_ready);
  static constexpr int kRouteBlock = 32;
  static constexpr int kRoutePrefetch = 2;  // before route_targets(r), step prefetches slot r + this's followers
  void prefetch_routes(int b) const;
  // step_episode's phases (world.cpp), in the order it runs them.
  // The humans' next velocities, into new_velocity_ (targets_ready: route_targets(b) ran for this step).
  void human_velocities(int b, int worker, bool targets_ready = false);
  bool live(int b) const { return buf_.status[b] == kRunning || buf_.status[b] == kContinuing; }  // stepped
  bool routes_slot(int b) const;  // human_routes applies to slot b now (a behaviour here, walls in its map)
  void route_targets(int b);      // routes_slot(b): each human's route point for this step, into targets_
  Vec2 robot_velocity(int b, const double* actions, double& theta);  // the action, clipped; turns theta
  Vec2 diff_drive_velocity(int b, const double* actions, double& theta, double v_max);  // within its limits
  struct RobotContacts {
    double dmin = std::numeric_limits<double>::infinity();  // swept clearance to the nearest human [m]
    bool hit_obstacle = false;                              // the swept disc touched a static obstacle
  };
  RobotContacts robot_contacts(int b, Vec2 v_robot) const;
  void move_agents(int b, Vec2 v_robot, double theta);
  bool record_arrivals(int b, double t);  // first arrivals at t; whether every human has arrived
  int count_overlaps(int b) const;        // human-human overlaps after the move
  void settle_outcome(int b, const RobotContacts& contacts, bool all_humans_arrived, int steps, double t_before,
                      double t);  // outcome, reward, collision kind, end step, status and done
  void require_human_velocities() const;
  void record(int b, int sample);
  struct GenerationScratch {
    std::vector<double> start, goal, radius, v_pref;
  };
  void load_one(const ScenarioConfig& scenario, int64_t b, int64_t seed, int32_t* failure, GenerationScratch& scratch);
  void observe_one(int b, const ObservationBuffers& obs, int64_t row) const;  // slot b into obs row `row`
  // world_sensing.cpp: the detected humans into obs row `row` (over the exact ones), the lidar scan, and
  // the latency's record of the state after step `step`.
  void sense_humans(int b, const ObservationBuffers& obs, int64_t row) const;
  void scan_lidar(int b, float* out) const;
  void remember_for_sensing(int b, int step);

  WorldConfig config_;
  WorldBuffers buf_;
  std::vector<double> new_velocity_;           // (B, A, 2) scratch
  std::vector<double> twist_;                  // (B, 2) the diff drive's (v, omega) of the last step
  std::unique_ptr<HumanBehaviour> behaviour_;  // null: the caller gives the velocities
  const double* given_velocity_ = nullptr;     // (B, A, 2), see give_human_velocities
  std::vector<std::vector<Vec2>> preferred_;   // (threads, A) the humans' preferred velocities
  std::vector<RouteFollower> routes_;          // (B, A) with human_routes: each human's route
  std::vector<double> targets_;                // (B, A, 2) with human_routes: where each human heads this step
  std::unique_ptr<ThreadPool> own_pool_;       // when no pool was given
  ThreadPool* pool_;
  std::vector<int64_t> refill_slots_;           // refill_done's finished slots, (B,) reserved
  std::vector<int> done_rank_;                  // (B,) rank among the finished slots (where done)
  std::vector<GenerationScratch> gen_scratch_;  // one per thread
  // Static obstacles: each slot's prepared map (null: open floor). A map equal to the one set last is
  // shared, not copied: a batch of one map holds one copy, which the step pass then reads from cache
  // for every slot.
  std::vector<std::shared_ptr<const PreparedObstacles>> slot_obstacles_;  // (B,)
  std::shared_ptr<const PreparedObstacles> last_obstacles_;
  SensingConfig sensing_;
  bool detections_exact_ = true;
  const int64_t* episode_seed_ = nullptr;    // (B,), see set_sensing
  std::vector<double> beam_cos_, beam_sin_;  // (beams,) relative to the sensor's heading
  std::vector<double> sensed_history_;       // with latency: (B, latency + 1, 4A + 1) world states
  std::vector<double> last_vertices_;        // the flat polygons last_obstacles_ was prepared from
  std::vector<int64_t> last_offsets_;
};

}  // namespace socialnav
