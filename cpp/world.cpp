#include "world.hpp"

#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>

#include "observation_layout.hpp"

// step_episode's phases are functions of their own for reading, inlined into it for speed (each runs
// once per slot and step; as calls they cost the linear humans' step a fifth of its time).
#define SOCIALNAV_PHASE [[gnu::always_inline]] inline

namespace socialnav {

namespace {

constexpr double kTimeEps = 1e-9;

inline Vec2 load(const double* p) { return Vec2{p[0], p[1]}; }
inline void store(double* p, Vec2 v) {
  p[0] = v.x;
  p[1] = v.y;
}

// Minimum distance between two discs' centres over [0, dt] when both move linearly:
// relative position d(t) = d0 + dv t.
inline double swept_centre_distance(Vec2 d0, Vec2 dv, double dt) {
  const double dv_sq = abs_sq(dv);
  double t = 0.0;
  if (dv_sq > 0.0) t = std::min(std::max(-dot(d0, dv) / dv_sq, 0.0), dt);
  return norm(d0 + t * dv);
}

}  // namespace

World::World(const WorldConfig& config, const WorldBuffers& buffers, ThreadPool* pool)
    : config_(config), buf_(buffers) {
  if (config.batch < 1) throw std::invalid_argument("batch must be >= 1, got " + std::to_string(config.batch));
  if (config.agents < 1) throw std::invalid_argument("agents must be >= 1");
  if (!(config.dt > 0.0)) throw std::invalid_argument("dt must be > 0");
  const int threads = std::max(1, config.threads);
  if (!config.human_behaviour.empty())  // checks the name and the parameters
    behaviour_ = make_human_behaviour(config.human_behaviour, config.human_params, threads, config.agents);
  else if (!config.human_params.empty())
    throw std::invalid_argument("human_params given without a human_behaviour");
  new_velocity_.assign(static_cast<size_t>(config.batch) * config.agents * 2, 0.0);
  twist_.assign(static_cast<size_t>(config.batch) * 2, 0.0);
  if (config.kinematics == kDiffDrive &&
      !(config.max_linear_accel > 0.0 && config.max_angular_accel > 0.0 && config.max_reverse_speed >= 0.0))
    throw std::invalid_argument("the differential drive's acceleration limits must be > 0, its reverse speed >= 0");
  preferred_.assign(threads, std::vector<Vec2>(config.agents));
  if (config.human_routes) {
    if (!(config.route_clearance >= 0.0) || !std::isfinite(config.route_clearance))
      throw std::invalid_argument("route_clearance must be finite and >= 0, got " +
                                  std::to_string(config.route_clearance));
    routes_.resize(static_cast<size_t>(config.batch) * config.agents);
    targets_.assign(static_cast<size_t>(config.batch) * config.agents * 2, 0.0);
  }
  if (pool && pool->size() != threads)
    throw std::invalid_argument("the pool has " + std::to_string(pool->size()) + " threads, the world " +
                                std::to_string(threads));
  if (!pool) own_pool_ = std::make_unique<ThreadPool>(threads);
  pool_ = pool ? pool : own_pool_.get();
  refill_slots_.reserve(static_cast<size_t>(config.batch));
  done_rank_.assign(static_cast<size_t>(config.batch), -1);
  if (config.max_obstacle_vertices < 0)
    throw std::invalid_argument("max_obstacle_vertices must be >= 0, got " +
                                std::to_string(config.max_obstacle_vertices));
  slot_obstacles_.resize(static_cast<size_t>(config.batch));
  gen_scratch_.resize(threads);
  for (GenerationScratch& g : gen_scratch_) {
    g.start.resize(2 * (config.agents - 1));
    g.goal.resize(2 * (config.agents - 1));
    g.radius.resize(config.agents - 1);
    g.v_pref.resize(config.agents - 1);
  }
}

void World::set_obstacles(int b, const double* vertices, const int64_t* offsets, int n_polygons) {
  if (b < 0 || b >= config_.batch) throw std::invalid_argument("slot " + std::to_string(b) + " out of range");
  if (n_polygons < 0) throw std::invalid_argument("n_polygons must be >= 0");
  const int64_t count = n_polygons > 0 ? offsets[n_polygons] : 0;
  if (n_polygons > 0 && offsets[0] != 0) throw std::invalid_argument("obstacle offsets must start at 0");
  for (int p = 0; p < n_polygons; ++p)
    if (offsets[p + 1] < offsets[p]) throw std::invalid_argument("obstacle offsets must not decrease");
  if (count > config_.max_obstacle_vertices)
    throw std::invalid_argument(
        "a static map of " + std::to_string(count) +
        " vertices exceeds max_obstacle_vertices = " + std::to_string(config_.max_obstacle_vertices));
  if (n_polygons == 0) {
    slot_obstacles_[b].reset();
    return;
  }
  const size_t n_offsets = static_cast<size_t>(n_polygons) + 1;
  const bool same_as_last =
      last_obstacles_ && last_offsets_.size() == n_offsets &&
      std::memcmp(last_offsets_.data(), offsets, n_offsets * sizeof(int64_t)) == 0 &&
      std::memcmp(last_vertices_.data(), vertices, static_cast<size_t>(2 * count) * sizeof(double)) == 0;
  if (!same_as_last) {
    // Prepared (and validated) before anything changes: a bad map leaves the slot as it was.
    auto prepared = std::make_shared<const PreparedObstacles>(prepare_obstacles(vertices, offsets, n_polygons));
    last_vertices_.assign(vertices, vertices + 2 * count);
    last_offsets_.assign(offsets, offsets + n_offsets);
    last_obstacles_ = std::move(prepared);
  }
  slot_obstacles_[b] = last_obstacles_;
}

void World::record(int b, int sample) {
  if (!buf_.hist_position || sample >= config_.history_len) return;
  const int A = config_.agents;
  const size_t src = static_cast<size_t>(b) * A * 2;
  const size_t dst = (static_cast<size_t>(b) * config_.history_len + sample) * A * 2;
  for (int k = 0; k < A * 2; ++k) {
    buf_.hist_position[dst + k] = buf_.position[src + k];
    buf_.hist_velocity[dst + k] = buf_.velocity[src + k];
  }
  if (buf_.hist_dmin) buf_.hist_dmin[static_cast<size_t>(b) * config_.history_len + sample] = buf_.dmin[b];
}

void World::human_velocities(int b, int worker, bool targets_ready) {
  const int A = config_.agents;
  const size_t row = static_cast<size_t>(b) * A;
  const uint8_t* mask = buf_.mask + row;
  double* out = new_velocity_.data() + row * 2;
  if (!behaviour_) {  // a behaviour outside the core gave them
    const double* given = given_velocity_ + row * 2;
    for (int i = 1; i < A; ++i) {
      if (!mask[i]) continue;
      out[2 * i] = given[2 * i];
      out[2 * i + 1] = given[2 * i + 1];
    }
    return;
  }
  SlotView slot;
  slot.agents = A;
  slot.position = buf_.position + row * 2;
  slot.velocity = buf_.velocity + row * 2;
  slot.goal = buf_.goal + row * 2;
  slot.radius = buf_.radius + row;
  slot.v_pref = buf_.v_pref + row;
  slot.mask = mask;
  slot.robot_visible = config_.robot_visible;
  slot.obstacles = obstacles(b);
  slot.orca_obstacles = orca_obstacles(b);
  slot.dt = config_.dt;
  // Where each human wants to go (its goal, or the point of its route it heads for), then how it avoids
  // the others (behaviour.hpp).
  const double* targets = slot.goal;
  if (routes_slot(b)) {
    if (!targets_ready) route_targets(b);
    targets = targets_.data() + row * 2;
  }
  Vec2* preferred = preferred_[worker].data();
  behaviour_->preferred_velocities(slot, targets, preferred);
  slot.preferred = preferred;
  behaviour_->velocities(slot, worker, out);
}

// The three cache lines of each of slot b's followers that a step reads (RouteFollower), requested ahead:
// a batch's followers are megabytes, and each line is otherwise a miss that stalls the step.
void World::prefetch_routes(int b) const {
  const RouteFollower* f = routes_.data() + static_cast<size_t>(b) * config_.agents;
  for (int i = 1; i < config_.agents; ++i)
    for (int line = 0; line < 3; ++line) __builtin_prefetch(reinterpret_cast<const char*>(f + i) + 64 * line);
}

bool World::routes_slot(int b) const { return config_.human_routes && behaviour_ && obstacles(b).count > 0; }

// Each human's route point for this step (routes.hpp); routes are planned at an episode's first step
// (again if asked twice before it: the episode's state is the same) and re-planned by the follower.
void World::route_targets(int b) {
  const int A = config_.agents;
  const size_t row = static_cast<size_t>(b) * A;
  const ObstacleView walls = obstacles(b);
  const uint8_t* mask = buf_.mask + row;
  const double* position = buf_.position + row * 2;
  const double* goal_of = buf_.goal + row * 2;
  const double* radius = buf_.radius + row;
  double* out = targets_.data() + row * 2;
  const bool start = buf_.steps[b] == 0;
  for (int i = 1; i < A; ++i) {
    if (!mask[i]) continue;
    RouteFollower& follower = routes_[row + i];
    const Vec2 p{position[2 * i], position[2 * i + 1]}, goal{goal_of[2 * i], goal_of[2 * i + 1]};
    if (start) follower.plan(walls, p, goal, radius[i], config_.route_clearance, slot_obstacles_[b]);
    const Vec2 t = follower.target(walls, p, goal, radius[i], config_.route_clearance, buf_.steps[b], config_.dt, i);
    out[2 * i] = t.x;
    out[2 * i + 1] = t.y;
  }
}

// Per human: points K, found, inflation, index, replans, yields, best_remaining, stalled, yielding, last_step,
// then the K points (x, y) and their K remaining lengths. The graphs are looked up again, and the skipped-test
// memory starts empty (it only spares tests whose answer it knows).
std::vector<double> World::route_state(int b) const {
  if (b < 0 || b >= config_.batch) throw std::invalid_argument("slot " + std::to_string(b) + " out of range");
  std::vector<double> out;
  if (!config_.human_routes) return out;
  const size_t row = static_cast<size_t>(b) * config_.agents;
  for (int i = 1; i < config_.agents; ++i) {
    const RouteFollower& f = routes_[row + i];
    const Route& r = f.route;
    out.insert(out.end(), {static_cast<double>(r.point.size()), r.found ? 1.0 : 0.0, r.inflation,
                           static_cast<double>(f.index), static_cast<double>(f.replans), static_cast<double>(f.yields),
                           f.best_remaining, f.stalled, f.yielding, static_cast<double>(f.last_step)});
    for (const Vec2& p : r.point) out.insert(out.end(), {p.x, p.y});
    out.insert(out.end(), r.remaining.begin(), r.remaining.end());
  }
  return out;
}

void World::set_route_state(int b, const double* state, size_t size) {
  if (b < 0 || b >= config_.batch) throw std::invalid_argument("slot " + std::to_string(b) + " out of range");
  if (!config_.human_routes) {
    if (size) throw std::invalid_argument("route state given to a world without human_routes");
    return;
  }
  constexpr size_t kHeader = 10;
  const size_t row = static_cast<size_t>(b) * config_.agents;
  size_t at = 0;
  std::vector<RouteFollower> restored(static_cast<size_t>(config_.agents));
  for (int i = 1; i < config_.agents; ++i) {
    if (at + kHeader > size) throw std::invalid_argument("route state: too short for slot " + std::to_string(b));
    const double* h = state + at;
    const auto k = static_cast<size_t>(h[0]);
    if (!(h[0] >= 0.0) || static_cast<double>(k) != h[0] || at + kHeader + 3 * k > size)
      throw std::invalid_argument("route state: malformed entry for human " + std::to_string(i));
    RouteFollower& f = restored[i];
    f.route.found = h[1] != 0.0;
    f.route.inflation = h[2];
    f.index = static_cast<int>(h[3]);
    f.replans = static_cast<int>(h[4]);
    f.yields = static_cast<int>(h[5]);
    f.best_remaining = h[6];
    f.stalled = h[7];
    f.yielding = h[8];
    f.last_step = static_cast<int>(h[9]);
    if (k > 0 && (f.index < 0 || static_cast<size_t>(f.index) >= k))
      throw std::invalid_argument("route state: index out of range for human " + std::to_string(i));
    const double* pts = h + kHeader;
    for (size_t j = 0; j < k; ++j) f.route.point.push_back(Vec2{pts[2 * j], pts[2 * j + 1]});
    f.route.remaining.assign(pts + 2 * k, pts + 3 * k);
    f.sync();
    if (f.route.found) {  // the graphs of this slot's map, for its re-plans and tests
      const ObstacleView walls = obstacles(b);
      const double radius = buf_.radius[row + i];
      if (walls.count == 0) throw std::invalid_argument("route state for a slot without obstacles");
      f.wide_graph = cached_route_graph(walls, radius + config_.route_clearance);
      f.held_map = slot_obstacles_[b];
    }
    at += kHeader + 3 * k;
  }
  if (at != size) throw std::invalid_argument("route state: " + std::to_string(size - at) + " values left over");
  for (int i = 1; i < config_.agents; ++i) routes_[row + i] = std::move(restored[i]);
}

// One slot's step, in phases: the humans decide (from the state before anyone moves), the robot's action
// becomes a velocity, the robot's swept contacts over the step, everyone moves, first arrivals, the
// human-human overlaps, then the outcome and reward. A continuing slot (kContinuing: the robot parked
// at its goal, the humans walking on for M_III) runs the same phases with a robot that stands still and
// tests nothing but whether the continuation is over.
void World::step_episode(int b, const double* actions, int worker, bool targets_ready) {
  int8_t& status = buf_.status[b];
  buf_.done[b] = 0;
  buf_.reward[b] = 0.0;
  if (!live(b)) return;
  const bool running = status == kRunning;
  if (buf_.steps[b] == 0) {
    record(b, 0);
    if (sensing_.latency > 0) remember_for_sensing(b, 0);
  }

  human_velocities(b, worker, targets_ready);
  double theta = buf_.theta[b];
  const Vec2 v_robot = running ? robot_velocity(b, actions, theta) : Vec2{};
  const RobotContacts contacts = running ? robot_contacts(b, v_robot) : RobotContacts{};
  buf_.dmin[b] = contacts.dmin;
  move_agents(b, v_robot, theta);
  const int steps = buf_.steps[b] + 1;
  buf_.steps[b] = steps;
  const double t_before = (steps - 1) * config_.dt;  // products, not sums: no drift over long episodes
  const double t = steps * config_.dt;
  const bool all_humans_arrived = record_arrivals(b, t);
  // Human-human overlaps never end an episode; CrowdSim does not count them. Counted over the robot's
  // episode only: not in the M_III continuation after its success.
  if (!config_.crowdsim_compat && running) buf_.overlaps[b] += count_overlaps(b);
  if (running) {
    settle_outcome(b, contacts, all_humans_arrived, steps, t_before, t);
  } else if (all_humans_arrived || t >= config_.continuation_cap - kTimeEps) {
    status = kSuccess;
    buf_.done[b] = 1;
  }
  record(b, steps);
  if (sensing_.latency > 0) remember_for_sensing(b, steps);
}

SOCIALNAV_PHASE Vec2 World::robot_velocity(int b, const double* actions, double& theta) {
  const double v_max = buf_.v_pref[static_cast<size_t>(b) * config_.agents];
  if (config_.kinematics == kHolonomic) {
    Vec2 v_robot{actions[2 * b], actions[2 * b + 1]};
    double speed = norm(v_robot);
    if (std::isinf(speed)) {  // |a|^2 overflowed (an action of 1e200): its direction, at v_pref
      v_robot = (1.0 / std::max(std::abs(v_robot.x), std::abs(v_robot.y))) * v_robot;
      speed = norm(v_robot);
    }
    if (speed > v_max) v_robot = (v_max / speed) * v_robot;
    return v_robot;
  }
  if (config_.kinematics == kDiffDrive) return diff_drive_velocity(b, actions, theta, v_max);
  const double v = std::min(std::max(actions[2 * b], -v_max), v_max);
  const double rot = std::min(std::max(actions[2 * b + 1], -config_.rotation_limit), config_.rotation_limit);
  // Wrapped to [0, 2*pi) as CrowdSim's Agent.step does: the learned policies' heading feature
  // (theta - goal direction) would otherwise grow with every turn the robot has made.
  theta = std::fmod(theta + rot, 2.0 * M_PI);
  if (theta < 0.0) theta += 2.0 * M_PI;
  return Vec2{v * std::cos(theta), v * std::sin(theta)};
}

// The differential drive: the command (v, d theta / dt) bounded to [-max_reverse_speed, v_pref] and
// |omega| <= rotation_limit / dt, then reached from the last step's (v, omega) within the acceleration limits
// (each bound on its own, as a velocity-space window: Fox, Burgard, Thrun, "The Dynamic Window Approach to
// Collision Avoidance", IEEE RA Magazine 1997). The robot then drives the arc of constant (v, omega) over the
// step exactly: its displacement is that arc's chord, of length v dt sinc(omega dt / 2) along the heading at
// mid-step, which the swept contacts test as the straight segment it is.
Vec2 World::diff_drive_velocity(int b, const double* actions, double& theta, double v_max) {
  const double dt = config_.dt;
  const Vec2 last = robot_twist(b);
  const double v0 = last.x, w0 = last.y;
  const double w_max = config_.rotation_limit / dt;
  const double v_cmd = std::min(std::max(actions[2 * b], -config_.max_reverse_speed), v_max);
  const double w_cmd = std::min(std::max(actions[2 * b + 1] / dt, -w_max), w_max);
  const double dv = config_.max_linear_accel * dt, dw = config_.max_angular_accel * dt;
  const double v = std::min(std::max(v_cmd, v0 - dv), v0 + dv);
  const double w = std::min(std::max(w_cmd, w0 - dw), w0 + dw);
  twist_[2 * static_cast<size_t>(b)] = v;
  twist_[2 * static_cast<size_t>(b) + 1] = w;
  const double half = 0.5 * w * dt;
  const double chord = half == 0.0 ? 1.0 : std::sin(half) / half;
  const double heading = theta + half;
  theta = std::fmod(theta + w * dt, 2.0 * M_PI);
  if (theta < 0.0) theta += 2.0 * M_PI;
  return Vec2{v * chord * std::cos(heading), v * chord * std::sin(heading)};
}

Vec2 World::robot_twist(int b, bool new_at_rest) const {
  if (new_at_rest && buf_.steps[b] == 0) return Vec2{};
  return Vec2{twist_[2 * static_cast<size_t>(b)], twist_[2 * static_cast<size_t>(b) + 1]};
}

void World::set_robot_twist(int b, double v, double omega) {
  if (b < 0 || b >= config_.batch) throw std::invalid_argument("slot " + std::to_string(b) + " out of range");
  if (!std::isfinite(v) || !std::isfinite(omega)) throw std::invalid_argument("robot twist must be finite");
  twist_[2 * static_cast<size_t>(b)] = v;
  twist_[2 * static_cast<size_t>(b) + 1] = omega;
}

SOCIALNAV_PHASE World::RobotContacts World::robot_contacts(int b, Vec2 v_robot) const {
  const int A = config_.agents;
  const double* pos = buf_.position + static_cast<size_t>(b) * A * 2;
  const double* vel = buf_.velocity + static_cast<size_t>(b) * A * 2;
  const double* radius = buf_.radius + static_cast<size_t>(b) * A;
  const uint8_t* mask = buf_.mask + static_cast<size_t>(b) * A;
  const double* new_vel = new_velocity_.data() + static_cast<size_t>(b) * A * 2;
  const double dt = config_.dt;
  // The robot against every human, both moving linearly over the step.
  const Vec2 p_robot = load(pos);
  RobotContacts out;
  for (int i = 1; i < A; ++i) {
    if (!mask[i]) continue;
    // CrowdSim sweeps with the human's previous velocity, not the one it applies now.
    const Vec2 v_h = config_.crowdsim_compat ? load(vel + 2 * i) : load(new_vel + 2 * i);
    const double d = swept_centre_distance(load(pos + 2 * i) - p_robot, v_h - v_robot, dt) - radius[0] - radius[i];
    out.dmin = std::min(out.dmin, d);
  }
  // The robot's swept disc against the static obstacles (a thin wall crossed within the step counts).
  const ObstacleView walls = obstacles(b);
  if (walls.count > 0) out.hit_obstacle = swept_disc_hits_obstacles(walls, p_robot, p_robot + dt * v_robot, radius[0]);
  return out;
}

SOCIALNAV_PHASE void World::move_agents(int b, Vec2 v_robot, double theta) {
  const int A = config_.agents;
  double* pos = buf_.position + static_cast<size_t>(b) * A * 2;
  double* vel = buf_.velocity + static_cast<size_t>(b) * A * 2;
  const uint8_t* mask = buf_.mask + static_cast<size_t>(b) * A;
  const double* new_vel = new_velocity_.data() + static_cast<size_t>(b) * A * 2;
  const double dt = config_.dt;
  store(pos, load(pos) + dt * v_robot);
  store(vel, v_robot);
  buf_.theta[b] = theta;
  for (int i = 1; i < A; ++i) {
    if (!mask[i]) continue;
    const Vec2 v = load(new_vel + 2 * i);
    store(pos + 2 * i, load(pos + 2 * i) + dt * v);
    store(vel + 2 * i, v);
  }
}

SOCIALNAV_PHASE bool World::record_arrivals(int b, double t) {
  const int A = config_.agents;
  const double* pos = buf_.position + static_cast<size_t>(b) * A * 2;
  const double* goal = buf_.goal + static_cast<size_t>(b) * A * 2;
  const double* radius = buf_.radius + static_cast<size_t>(b) * A;
  const uint8_t* mask = buf_.mask + static_cast<size_t>(b) * A;
  double* arrival = buf_.arrival + static_cast<size_t>(b) * A;
  // First arrivals (M_III) of every agent at the goal it had at reset.
  bool all_humans_arrived = true;
  for (int i = 0; i < A; ++i) {
    if (!mask[i]) continue;
    if (std::isnan(arrival[i]) && norm(load(pos + 2 * i) - load(goal + 2 * i)) < radius[i]) arrival[i] = t;
    if (i > 0 && std::isnan(arrival[i])) all_humans_arrived = false;
  }
  return all_humans_arrived;
}

SOCIALNAV_PHASE int World::count_overlaps(int b) const {
  const int A = config_.agents;
  const double* pos = buf_.position + static_cast<size_t>(b) * A * 2;
  const double* radius = buf_.radius + static_cast<size_t>(b) * A;
  const uint8_t* mask = buf_.mask + static_cast<size_t>(b) * A;
  int count = 0;
  for (int i = 1; i < A; ++i) {
    if (!mask[i]) continue;
    for (int j = i + 1; j < A; ++j) {
      if (!mask[j]) continue;
      const double r = radius[i] + radius[j];
      if (abs_sq(load(pos + 2 * i) - load(pos + 2 * j)) < r * r) ++count;
    }
  }
  return count;
}

SOCIALNAV_PHASE void World::settle_outcome(int b, const RobotContacts& contacts, bool all_humans_arrived, int steps,
                                           double t_before, double t) {
  const int A = config_.agents;
  const double* pos = buf_.position + static_cast<size_t>(b) * A * 2;
  const double* goal = buf_.goal + static_cast<size_t>(b) * A * 2;
  const double* radius = buf_.radius + static_cast<size_t>(b) * A;
  int8_t& status = buf_.status[b];
  const double dmin = contacts.dmin;
  const bool reached = norm(load(pos) - load(goal)) < radius[0];
  const bool hit_human = dmin < 0.0;
  const bool collided = hit_human || (contacts.hit_obstacle && config_.obstacle_collision_ends);
  int8_t outcome = kRunning;
  if (config_.crowdsim_compat) {
    // CrowdSim tests the clock before the step and lets a timeout win over everything else.
    if (t_before >= config_.time_limit - 1.0 - kTimeEps)
      outcome = kTimeout;
    else if (collided)
      outcome = kCollision;
    else if (reached)
      outcome = kSuccess;
  } else {
    if (collided)
      outcome = kCollision;
    else if (reached)
      outcome = kSuccess;
    else if (t >= config_.time_limit - kTimeEps)
      outcome = kTimeout;
  }
  double reward = 0.0;
  // A human collision is the one reported when both happen in the same step (the human metrics'
  // collision rate must not lose it).
  if (outcome == kCollision)
    reward = hit_human ? config_.collision_penalty : config_.obstacle_collision_penalty;
  else if (outcome == kSuccess)
    reward = config_.success_reward;
  else if (outcome == kRunning && contacts.hit_obstacle)
    reward = config_.obstacle_collision_penalty;
  else if (outcome == kRunning && dmin < config_.discomfort_dist)
    reward = (dmin - config_.discomfort_dist) * config_.discomfort_penalty_factor * config_.dt;
  buf_.reward[b] = reward;
  if (outcome == kCollision && buf_.collision_kind)
    buf_.collision_kind[b] = hit_human ? kHumanCollision : kObstacleCollision;

  if (outcome != kRunning) {
    buf_.end_step[b] = steps;
    if (outcome == kSuccess && config_.continue_after_success && !all_humans_arrived &&
        t < config_.continuation_cap - kTimeEps) {
      status = kContinuing;  // the caller sees the outcome through end_step; done comes later
    } else {
      status = outcome;
      buf_.done[b] = 1;
    }
  }
}

void World::preview_humans(double* out) {
  require_human_velocities();
  const int A = config_.agents;
  const int N = A - 1;
  pool_->parallel_for(config_.batch, [&](int begin, int end, int worker) {
    for (int b = begin; b < end; ++b) {
      double* o = out + static_cast<size_t>(b) * N * 5;
      const double* pos = buf_.position + static_cast<size_t>(b) * A * 2;
      const double* radius = buf_.radius + static_cast<size_t>(b) * A;
      const uint8_t* mask = buf_.mask + static_cast<size_t>(b) * A;
      const bool stepped = live(b);
      if (stepped) human_velocities(b, worker);
      const double* v = new_velocity_.data() + static_cast<size_t>(b) * A * 2;
      for (int i = 1; i < A; ++i) {
        double* h = o + 5 * (i - 1);
        if (!stepped || !mask[i]) {
          h[0] = h[1] = h[2] = h[3] = h[4] = 0.0;
          continue;
        }
        h[0] = pos[2 * i] + config_.dt * v[2 * i];
        h[1] = pos[2 * i + 1] + config_.dt * v[2 * i + 1];
        h[2] = v[2 * i];
        h[3] = v[2 * i + 1];
        h[4] = radius[i];
      }
    }
  });
}

void World::observe_one(int b, const ObservationBuffers& o, int64_t row) const {
  const int A = config_.agents;
  const int N = A - 1;
  const double* pos = buf_.position + static_cast<size_t>(b) * A * 2;
  const double* vel = buf_.velocity + static_cast<size_t>(b) * A * 2;
  const double* goal = buf_.goal + static_cast<size_t>(b) * A * 2;
  const double* radius = buf_.radius + static_cast<size_t>(b) * A;
  const uint8_t* mask = buf_.mask + static_cast<size_t>(b) * A;
  double* r = o.robot + static_cast<size_t>(row) * kRobotFeatures;
  r[0] = pos[0];
  r[1] = pos[1];
  r[2] = vel[0];
  r[3] = vel[1];
  r[4] = radius[0];
  r[5] = goal[0];
  r[6] = goal[1];
  r[7] = buf_.v_pref[static_cast<size_t>(b) * A];
  r[8] = buf_.theta[b];
  for (int i = 1; i < A; ++i) {
    double* h = o.humans + (static_cast<size_t>(row) * N + (i - 1)) * kHumanFeatures;
    const bool real = mask[i] != 0;
    o.human_mask[static_cast<size_t>(row) * N + (i - 1)] = real;
    if (!real) {
      h[0] = h[1] = h[2] = h[3] = h[4] = 0.0;
      continue;
    }
    h[0] = pos[2 * i];
    h[1] = pos[2 * i + 1];
    h[2] = vel[2 * i];
    h[3] = vel[2 * i + 1];
    h[4] = radius[i];
  }
  o.active[row] = buf_.status[b] == kRunning;
  o.time[row] = static_cast<double>(buf_.steps[b]) * config_.dt;
  if (!detections_exact_) sense_humans(b, o, row);
  if (o.lidar) scan_lidar(b, o.lidar + static_cast<size_t>(row) * sensing_.lidar_beams);
}

void World::observe(const ObservationBuffers& o) {
  pool_->parallel_for(config_.batch, [&](int begin, int end, int) {
    for (int b = begin; b < end; ++b) observe_one(b, o, b);
  });
}

namespace {

// 0 when every agent's start and goal disc clears the obstacles, else -(1 + 2a) for the start of agent a
// or -(2 + 2a) for its goal (agent 0 is the robot). Kept out of line: World::load_one runs inside the
// refill pass over every slot, which it should not make larger.
[[gnu::noinline]] int covered_start_or_goal(const ObstacleView& walls, const double* pos, const double* goal,
                                            const double* radius, int agents) {
  for (int a = 0; a < agents; ++a) {
    const Vec2 start{pos[2 * a], pos[2 * a + 1]}, end{goal[2 * a], goal[2 * a + 1]};
    if (disc_touches_obstacles(walls, start, radius[a])) return -(1 + 2 * a);
    if (disc_touches_obstacles(walls, end, radius[a])) return -(2 + 2 * a);
  }
  return 0;
}

}  // namespace

void World::load_one(const ScenarioConfig& scenario, int64_t b, int64_t seed, int32_t* failure,
                     GenerationScratch& scratch) {
  const int A = config_.agents;
  const double r = scenario.circle_radius;
  *failure = generate_humans(scenario, seed, scratch.start.data(), scratch.goal.data(), scratch.radius.data(),
                             scratch.v_pref.data());
  if (*failure != 0) {
    buf_.status[b] = kIdle;
    return;
  }
  double* pos = buf_.position + static_cast<size_t>(b) * A * 2;
  double* vel = buf_.velocity + static_cast<size_t>(b) * A * 2;
  double* gl = buf_.goal + static_cast<size_t>(b) * A * 2;
  double* rad = buf_.radius + static_cast<size_t>(b) * A;
  double* vp = buf_.v_pref + static_cast<size_t>(b) * A;
  uint8_t* mask = buf_.mask + static_cast<size_t>(b) * A;
  double* arrival = buf_.arrival + static_cast<size_t>(b) * A;
  // Scenario.generate: the robot starts at (0, -R) facing +y with goal (0, R).
  pos[0] = 0.0;
  pos[1] = -r;
  gl[0] = 0.0;
  gl[1] = r;
  rad[0] = scenario.robot_radius;
  vp[0] = scenario.robot_v_pref;
  mask[0] = 1;
  for (int j = 0; j < A - 1; ++j) {
    pos[2 * (j + 1)] = scratch.start[2 * j];
    pos[2 * (j + 1) + 1] = scratch.start[2 * j + 1];
    gl[2 * (j + 1)] = scratch.goal[2 * j];
    gl[2 * (j + 1) + 1] = scratch.goal[2 * j + 1];
    rad[j + 1] = scratch.radius[j];
    vp[j + 1] = scratch.v_pref[j];
    mask[j + 1] = 1;
  }
  for (int a = 0; a < 2 * A; ++a) vel[a] = 0.0;
  for (int a = 0; a < A; ++a) arrival[a] = std::numeric_limits<double>::quiet_NaN();
  // The slot's map may be one the scenario does not know (the World's static_map): an agent that would
  // start inside an obstacle, or head for a goal inside one, makes the episode fail instead of running.
  const ObstacleView walls = obstacles(static_cast<int>(b));
  if (walls.count > 0) {
    const int code = covered_start_or_goal(walls, pos, gl, rad, A);
    if (code != 0) {
      *failure = code;
      buf_.status[b] = kIdle;
      return;
    }
  }
  buf_.theta[b] = M_PI / 2;
  buf_.steps[b] = 0;
  buf_.reward[b] = 0.0;
  buf_.dmin[b] = std::numeric_limits<double>::infinity();
  buf_.done[b] = 0;
  buf_.overlaps[b] = 0;
  buf_.end_step[b] = -1;
  if (buf_.collision_kind) buf_.collision_kind[b] = kNoCollision;
  buf_.status[b] = kRunning;
}

void World::load_generated(const ScenarioConfig& scenario, const int64_t* slots, const int64_t* seeds, int k,
                           int32_t* failure) {
  pool_->parallel_for(k, [&](int begin, int end, int worker) {
    for (int i = begin; i < end; ++i) load_one(scenario, slots[i], seeds[i], failure + i, gen_scratch_[worker]);
  });
}

void World::require_human_velocities() const {
  if (!behaviour_ && !given_velocity_)
    throw std::invalid_argument("this world's human velocities come from its caller: give_human_velocities first");
}

int World::step(const double* actions, const StepOutputs* out) {
  const int B = config_.batch;
  require_human_velocities();
  for (int b = 0; b < B; ++b) {
    if (buf_.status[b] != kRunning) continue;
    if (!std::isfinite(actions[2 * b]) || !std::isfinite(actions[2 * b + 1]))
      throw std::invalid_argument("action of episode slot " + std::to_string(b) + " is not finite");
  }
  std::atomic<int> done_count{0};
  const double nan = std::numeric_limits<double>::quiet_NaN();
  pool_->parallel_for(B, [&](int begin, int end, int worker) {
    int done = 0;
    for (int b = begin; b < end; ++b) {
      // With routes, the route points of a block of slots first, then their steps: the followers (megabytes
      // for a batch) are read in one stream, the slots ahead requested while this one's are worked on
      // (docs/routes.md, "Cost": with this, the routed world's speed ratio no longer fell with the batch).
      if (config_.human_routes && (b - begin) % kRouteBlock == 0)
        for (int r = b; r < std::min(end, b + kRouteBlock); ++r) {
          if (r + kRoutePrefetch < end) prefetch_routes(r + kRoutePrefetch);
          if (live(r) && routes_slot(r)) route_targets(r);
        }
      step_episode(b, actions, worker, config_.human_routes);
      done += buf_.done[b];
      if (!out) continue;
      const bool ended = buf_.done[b] != 0;
      const int8_t status = buf_.status[b];
      out->reward[b] = buf_.reward[b];
      out->terminated[b] = ended && status != kTimeout;
      out->truncated[b] = ended && status == kTimeout;
      out->outcome[b] = ended ? status : static_cast<int8_t>(kRunning);
      out->final_dmin[b] = ended ? buf_.dmin[b] : nan;
      out->final_episode[b] = ended ? out->episode_index[b] : -1;
      if (out->collision_kind)
        out->collision_kind[b] =
            ended && status == kCollision && buf_.collision_kind ? buf_.collision_kind[b] : static_cast<int8_t>(0);
    }
    done_count.fetch_add(done, std::memory_order_relaxed);
  });
  return done_count.load();
}

int World::refill_done(const ScenarioConfig& scenario, const int64_t* indices, const int64_t* seeds, int count,
                       int64_t* episode_index, int64_t* episode_seed, int32_t* failure, const ObservationBuffers* obs,
                       const ObservationBuffers* final_obs) {
  const int B = config_.batch;
  // The finished slots in slot order. Few slots finish per step, so the scan skips 8 unfinished
  // slots per load (it is the serial part of the refill: ~B/8 loads instead of B reads and 2B writes).
  refill_slots_.clear();
  int b = 0;
  for (; b + 8 <= B; b += 8) {
    uint64_t word;
    std::memcpy(&word, buf_.done + b, sizeof(word));
    if (!word) continue;
    for (int i = b; i < b + 8; ++i)
      if (buf_.done[i]) refill_slots_.push_back(i);
  }
  for (; b < B; ++b)
    if (buf_.done[b]) refill_slots_.push_back(b);
  const int done = static_cast<int>(refill_slots_.size());
  const int k = std::min(done, std::max(count, 0));
  for (int r = 0; r < done; ++r) {
    const int64_t slot = refill_slots_[r];
    done_rank_[slot] = r;  // read only where done[slot] is set
    if (r >= k) {          // the stream is exhausted
      buf_.status[slot] = kIdle;
      episode_index[slot] = -1;
    }
  }
  if (obs || final_obs) {
    // One pass over the batch: a finished slot's final observation (row = its rank among the finished
    // slots), its new episode, then every slot's observation, while the slot is in this thread's cache
    // (one job and one pass over memory instead of three).
    pool_->parallel_for(B, [&](int begin, int end, int worker) {
      for (int s = begin; s < end; ++s) {
        if (buf_.done[s]) {
          const int r = done_rank_[s];
          if (final_obs) observe_one(s, *final_obs, r);
          if (r < k) load_one(scenario, s, seeds[r], failure + r, gen_scratch_[worker]);  // clears done
        }
        if (obs) observe_one(s, *obs, s);
      }
    });
  } else {
    load_generated(scenario, refill_slots_.data(), seeds, k, failure);
  }
  int failed = 0;
  for (int j = 0; j < k; ++j) {
    failed += failure[j] != 0;
    episode_index[refill_slots_[j]] = indices[j];
    episode_seed[refill_slots_[j]] = seeds[j];
  }
  return failed;
}

}  // namespace socialnav
