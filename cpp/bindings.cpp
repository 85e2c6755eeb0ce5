// Python bindings of the native core (private module socialnav._core).
// Arrays are float64/int C-contiguous NumPy arrays; the Python façade checks shapes and dtypes
// and these bindings check them again, so a wrong buffer raises instead of corrupting memory.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "behaviour.hpp"
#include "behaviours/builtin_params.hpp"
#include "multiversion.hpp"
#include "observation_layout.hpp"
#include "orca.hpp"
#include "robot_policies.hpp"
#include "routes.hpp"
#include "sarl_scorer.hpp"
#include "scenario_gen.hpp"
#include "sensing.hpp"
#include "social_force.hpp"
#include "world.hpp"

namespace nb = nanobind;
using namespace nb::literals;
using socialnav::Vec2;

template <typename T>
using Array = nb::ndarray<T, nb::numpy, nb::c_contig, nb::device::cpu>;

namespace {

template <typename T>
T* checked(Array<T>& a, const char* name, size_t expected) {
  if (a.size() != expected)
    throw std::invalid_argument(std::string(name) + ": expected " + std::to_string(expected) + " elements, got " +
                                std::to_string(a.size()));
  return a.data();
}

template <typename T>
T* optional_checked(nb::object obj, const char* name, size_t expected) {
  if (obj.is_none()) return nullptr;
  Array<T> a = nb::cast<Array<T>>(obj, /* convert = */ false);  // written in place: no copies
  return checked(a, name, expected);
}

// (robot, humans, human_mask, active, time) arrays of `rows` rows from a Python sequence, or false for None.
bool observation_buffers(nb::object arrays, const char* name, size_t rows, int humans, int lidar_beams,
                         socialnav::ObservationBuffers& out) {
  if (arrays.is_none()) return false;
  nb::sequence seq = nb::cast<nb::sequence>(arrays);
  const size_t given = nb::len(seq);
  if (given != 5 && given != 6)
    throw std::invalid_argument(std::string(name) + ": expected (robot, humans, human_mask, active, time[, lidar])");
  const size_t N = static_cast<size_t>(humans);
  out.robot = optional_checked<double>(seq[0], "robot", rows * socialnav::kRobotFeatures);
  out.humans = optional_checked<double>(seq[1], "humans", rows * N * socialnav::kHumanFeatures);
  out.human_mask = reinterpret_cast<uint8_t*>(optional_checked<bool>(seq[2], "human_mask", rows * N));
  out.active = reinterpret_cast<uint8_t*>(optional_checked<bool>(seq[3], "active", rows));
  out.time = optional_checked<double>(seq[4], "time", rows);
  if (!out.robot || !out.humans || !out.human_mask || !out.active || !out.time)
    throw std::invalid_argument(std::string(name) + ": none of the five arrays may be None");
  out.lidar = given == 6 ? optional_checked<float>(seq[5], "lidar", rows * static_cast<size_t>(lidar_beams)) : nullptr;
  if (out.lidar && lidar_beams == 0)
    throw std::invalid_argument(std::string(name) + ": a lidar array for a world without lidar");
  return true;
}

// Values of behaviour `name`'s parameters from Python: None (the defaults), a dict of some of them by
// name (the others keep their defaults; an undeclared name is refused) or a sequence of all of them in
// declared order. Checked against the declaration (ValueError naming the parameter).
socialnav::ParamValues behaviour_values(const std::string& name, nb::handle given) {
  const socialnav::BehaviourInfo& info = socialnav::human_behaviour(name);
  std::vector<double> values;
  if (nb::isinstance<nb::dict>(given)) {
    for (const socialnav::BehaviourParam& p : info.params) values.push_back(p.default_value);
    for (auto [key, value] : nb::borrow<nb::dict>(given)) {
      const std::string k = nb::cast<std::string>(key);
      size_t at = 0;
      while (at < info.params.size() && info.params[at].name != k) ++at;
      if (at == info.params.size()) {
        std::string names;
        for (const socialnav::BehaviourParam& p : info.params) names += (names.empty() ? "" : ", ") + p.name;
        throw std::invalid_argument(name + " declares no parameter '" + k + "'; declared: " + names);
      }
      values[at] = nb::cast<double>(value);
    }
  } else if (!given.is_none()) {
    values = nb::cast<std::vector<double>>(given);
  }
  return socialnav::ParamValues(info.name, info.params, values);
}

// A declared number as Python reads it best: an int when whole (bounds 0 and 64 print as such), None for NaN.
nb::object declared_number(double x, bool integer) {
  if (std::isnan(x)) return nb::none();
  if (integer || (x == std::floor(x) && std::abs(x) < 9007199254740992.0)) return nb::int_(static_cast<int64_t>(x));
  return nb::float_(x);
}

nb::list behaviour_descriptors() {
  nb::list out;
  for (const socialnav::BehaviourInfo* info : socialnav::human_behaviours()) {
    nb::list params;
    for (const socialnav::BehaviourParam& p : info->params) {
      nb::dict d;
      d["name"] = p.name;
      d["default"] = p.integer ? nb::object(nb::int_(static_cast<int64_t>(p.default_value)))
                               : nb::object(nb::float_(p.default_value));
      d["type"] = p.integer ? "int" : "float";
      d["unit"] = p.unit;
      d["description"] = p.description;
      d["gt"] = declared_number(p.gt, p.integer);
      d["ge"] = declared_number(p.ge, p.integer);
      d["lt"] = declared_number(p.lt, p.integer);
      d["le"] = declared_number(p.le, p.integer);
      params.append(d);
    }
    nb::dict entry;
    entry["name"] = info->name;
    entry["description"] = info->description;
    entry["parameters"] = params;
    out.append(entry);
  }
  return out;
}

// A built-in scenario generates into a world only with one human slot per human.
void check_fits(const socialnav::ScenarioConfig& scenario, const socialnav::WorldConfig& world) {
  if (scenario.n_humans != world.agents - 1)
    throw std::invalid_argument("scenario n_humans " + std::to_string(scenario.n_humans) +
                                " does not match the world's " + std::to_string(world.agents - 1) + " human slots");
}

// Keeps the arrays alive for as long as the world points into them.
struct PyWorld {
  nb::list keep_alive;
  nb::object given_velocity;  // the array of give_human_velocities
  nb::object episode_seed;    // the array of set_sensing
  std::unique_ptr<socialnav::World> world;
};

Vec2 vec(const Array<double>& a) { return Vec2{a.data()[0], a.data()[1]}; }

// Checks flat polygons (vertices (V, 2), offsets (P + 1,)) and returns P.
int polygon_count(const Array<double>& vertices, const Array<int64_t>& offsets) {
  if (offsets.size() < 1) throw std::invalid_argument("obstacle offsets must have P + 1 >= 1 entries");
  const size_t P = offsets.size() - 1;
  const int64_t* o = offsets.data();
  if (o[0] != 0) throw std::invalid_argument("obstacle offsets must start at 0");
  for (size_t p = 0; p < P; ++p)
    if (o[p + 1] < o[p]) throw std::invalid_argument("obstacle offsets must not decrease");
  if (vertices.size() != static_cast<size_t>(2 * o[P]))
    throw std::invalid_argument("obstacle vertices: expected " + std::to_string(o[P]) + " x 2 values, got " +
                                std::to_string(vertices.size()));
  return static_cast<int>(P);
}

// The view of B episodes' prepared maps (a PreparedObstacleBatch), empty for None; a batch prepared for another
// number of episodes is refused, the message ending "<what> B".
socialnav::ObstacleBatchView batch_walls(const nb::object& obstacles, size_t B, const char* what) {
  if (obstacles.is_none()) return socialnav::ObstacleBatchView{};
  const auto& walls = nb::cast<const socialnav::PreparedObstacleBatch&>(obstacles);
  if (walls.first.size() != B)
    throw std::invalid_argument("obstacles: prepared for " + std::to_string(walls.first.size()) + " episodes, " + what +
                                std::to_string(B));
  return walls.view();
}

// The B episodes' maps prepared once (obstacles.hpp), after the flat arrays' checks.
socialnav::PreparedObstacleBatch prepare_batch(const Array<double>& vertices, const Array<int64_t>& offsets,
                                               const Array<int64_t>& episode_polygons, size_t B) {
  const int P = polygon_count(vertices, offsets);
  if (episode_polygons.size() != B + 1)
    throw std::invalid_argument("episode_polygons: expected B + 1 = " + std::to_string(B + 1) + " entries");
  return socialnav::prepare_obstacle_batch(vertices.data(), offsets.data(), P, episode_polygons.data(),
                                           static_cast<int64_t>(B));
}

}  // namespace

NB_MODULE(_core, m) {
  m.doc() = "socialnav native core: ORCA, social force and the batched crowd world.";

  m.def("human_behaviours", &behaviour_descriptors,
        "The registered pedestrian behaviours in listing order: dicts of name, description and parameters "
        "(dicts of name, default, type 'float' or 'int', unit, description and the bounds gt, ge, lt, le, None "
        "where unbounded), as each behaviour declares them (cpp/behaviours/).");

  using S = socialnav::SensingConfig;
  nb::class_<S>(m, "SensingConfig")
      .def(nb::init<>())
      .def_rw("range", &S::range)
      .def_rw("fov", &S::fov)
      .def_rw("occlusion_walls", &S::occlusion_walls)
      .def_rw("occlusion_humans", &S::occlusion_humans)
      .def_rw("position_noise", &S::position_noise)
      .def_rw("velocity_noise", &S::velocity_noise)
      .def_rw("dropout", &S::dropout)
      .def_rw("latency", &S::latency)
      .def_rw("lidar_beams", &S::lidar_beams)
      .def_rw("lidar_fov", &S::lidar_fov)
      .def_rw("lidar_range", &S::lidar_range)
      .def_rw("lidar_noise", &S::lidar_noise);

  using C = socialnav::WorldConfig;
  nb::class_<C>(m, "WorldConfig")
      .def(nb::init<>())
      .def_rw("batch", &C::batch)
      .def_rw("agents", &C::agents)
      .def_rw("dt", &C::dt)
      .def_rw("time_limit", &C::time_limit)
      .def_rw("human_behaviour", &C::human_behaviour)
      .def_rw("human_params", &C::human_params)
      .def_rw("robot_visible", &C::robot_visible)
      .def_rw("kinematics", &C::kinematics)
      .def_rw("rotation_limit", &C::rotation_limit)
      .def_rw("max_linear_accel", &C::max_linear_accel)
      .def_rw("max_angular_accel", &C::max_angular_accel)
      .def_rw("max_reverse_speed", &C::max_reverse_speed)
      .def_rw("crowdsim_compat", &C::crowdsim_compat)
      .def_rw("discomfort_dist", &C::discomfort_dist)
      .def_rw("success_reward", &C::success_reward)
      .def_rw("collision_penalty", &C::collision_penalty)
      .def_rw("discomfort_penalty_factor", &C::discomfort_penalty_factor)
      .def_rw("continue_after_success", &C::continue_after_success)
      .def_rw("continuation_cap", &C::continuation_cap)
      .def_rw("history_len", &C::history_len)
      .def_rw("threads", &C::threads)
      .def_rw("max_obstacle_vertices", &C::max_obstacle_vertices)
      .def_rw("obstacle_collision_penalty", &C::obstacle_collision_penalty)
      .def_rw("obstacle_collision_ends", &C::obstacle_collision_ends)
      .def_rw("human_routes", &C::human_routes)
      .def_rw("route_clearance", &C::route_clearance);

  m.attr("STATUS_IDLE") = static_cast<int>(socialnav::kIdle);
  m.attr("STATUS_RUNNING") = static_cast<int>(socialnav::kRunning);
  m.attr("STATUS_SUCCESS") = static_cast<int>(socialnav::kSuccess);
  m.attr("STATUS_COLLISION") = static_cast<int>(socialnav::kCollision);
  m.attr("STATUS_TIMEOUT") = static_cast<int>(socialnav::kTimeout);
  m.attr("STATUS_CONTINUING") = static_cast<int>(socialnav::kContinuing);
  m.attr("COLLISION_NONE") = static_cast<int>(socialnav::kNoCollision);
  m.attr("COLLISION_HUMAN") = static_cast<int>(socialnav::kHumanCollision);
  m.attr("ROBOT_FEATURES") = socialnav::kRobotFeatures;  // observation_layout.hpp
  m.attr("HUMAN_FEATURES") = socialnav::kHumanFeatures;
  m.attr("COLLISION_OBSTACLE") = static_cast<int>(socialnav::kObstacleCollision);
  m.attr("HOLONOMIC") = static_cast<int>(socialnav::kHolonomic);
  m.attr("UNICYCLE") = static_cast<int>(socialnav::kUnicycle);
  m.attr("DIFF_DRIVE") = static_cast<int>(socialnav::kDiffDrive);

  nb::class_<PyWorld>(m, "World")
      .def(
          "__init__",
          [](PyWorld* self, const C& config, Array<double> position, Array<double> velocity, Array<double> goal,
             Array<double> radius, Array<double> v_pref, Array<uint8_t> mask, Array<double> theta, Array<int32_t> steps,
             Array<int8_t> status, Array<double> reward, Array<double> dmin, Array<uint8_t> done,
             Array<int32_t> overlaps, Array<double> arrival, Array<int32_t> end_step, nb::object hist_position,
             nb::object hist_velocity, nb::object hist_dmin, nb::object pool, nb::object collision_kind) {
            const size_t B = static_cast<size_t>(config.batch);
            const size_t A = static_cast<size_t>(config.agents);
            const size_t T = static_cast<size_t>(config.history_len);
            socialnav::WorldBuffers buf{};
            buf.position = checked(position, "position", B * A * 2);
            buf.velocity = checked(velocity, "velocity", B * A * 2);
            buf.goal = checked(goal, "goal", B * A * 2);
            buf.radius = checked(radius, "radius", B * A);
            buf.v_pref = checked(v_pref, "v_pref", B * A);
            buf.mask = checked(mask, "mask", B * A);
            buf.theta = checked(theta, "theta", B);
            buf.steps = checked(steps, "steps", B);
            buf.status = checked(status, "status", B);
            buf.reward = checked(reward, "reward", B);
            buf.dmin = checked(dmin, "dmin", B);
            buf.done = checked(done, "done", B);
            buf.overlaps = checked(overlaps, "overlaps", B);
            buf.arrival = checked(arrival, "arrival", B * A);
            buf.end_step = checked(end_step, "end_step", B);
            buf.hist_position = optional_checked<double>(hist_position, "hist_position", B * T * A * 2);
            buf.hist_velocity = optional_checked<double>(hist_velocity, "hist_velocity", B * T * A * 2);
            buf.hist_dmin = optional_checked<double>(hist_dmin, "hist_dmin", B * T);
            buf.collision_kind = optional_checked<int8_t>(collision_kind, "collision_kind", B);
            if (T > 0 && (!buf.hist_position || !buf.hist_velocity || !buf.hist_dmin))
              throw std::invalid_argument("history_len > 0 needs hist_position, hist_velocity and hist_dmin");
            socialnav::ThreadPool* shared = pool.is_none() ? nullptr : nb::cast<socialnav::ThreadPool*>(pool);
            new (self) PyWorld();
            self->world = std::make_unique<socialnav::World>(config, buf, shared);
            for (nb::handle h :
                 {nb::cast(position), nb::cast(velocity), nb::cast(goal), nb::cast(radius), nb::cast(v_pref),
                  nb::cast(mask), nb::cast(theta), nb::cast(steps), nb::cast(status), nb::cast(reward), nb::cast(dmin),
                  nb::cast(done), nb::cast(overlaps), nb::cast(arrival), nb::cast(end_step)})
              self->keep_alive.append(h);
            self->keep_alive.append(hist_position);
            self->keep_alive.append(hist_velocity);
            self->keep_alive.append(hist_dmin);
            self->keep_alive.append(pool);  // a shared pool outlives the worlds that run on it
            self->keep_alive.append(collision_kind);
          },
          // State buffers are shared with Python: a converted copy would silently decouple them.
          "config"_a, "position"_a.noconvert(), "velocity"_a.noconvert(), "goal"_a.noconvert(), "radius"_a.noconvert(),
          "v_pref"_a.noconvert(), "mask"_a.noconvert(), "theta"_a.noconvert(), "steps"_a.noconvert(),
          "status"_a.noconvert(), "reward"_a.noconvert(), "dmin"_a.noconvert(), "done"_a.noconvert(),
          "overlaps"_a.noconvert(), "arrival"_a.noconvert(), "end_step"_a.noconvert(), "hist_position"_a.none(),
          "hist_velocity"_a.none(), "hist_dmin"_a.none(), "pool"_a.none() = nb::none(),
          "collision_kind"_a.none() = nb::none())
      .def(
          "step",
          [](PyWorld& self, Array<double> actions) {
            const auto& c = self.world->config();
            const double* a = checked(actions, "actions", static_cast<size_t>(c.batch) * 2);
            nb::gil_scoped_release release;
            self.world->step(a);
          },
          "actions"_a, "Advance every running episode by one step (GIL released).")
      .def(
          "step",
          [](PyWorld& self, Array<double> actions, Array<double> reward, Array<bool> terminated, Array<bool> truncated,
             Array<int8_t> outcome, Array<double> final_dmin, Array<int64_t> final_episode,
             Array<int64_t> episode_index, nb::object collision_kind) {
            const auto& c = self.world->config();
            const size_t B = static_cast<size_t>(c.batch);
            const double* a = checked(actions, "actions", B * 2);
            socialnav::StepOutputs out{};
            out.reward = checked(reward, "reward", B);
            out.terminated = reinterpret_cast<uint8_t*>(checked(terminated, "terminated", B));
            out.truncated = reinterpret_cast<uint8_t*>(checked(truncated, "truncated", B));
            out.outcome = checked(outcome, "outcome", B);
            out.final_dmin = checked(final_dmin, "final_dmin", B);
            out.final_episode = checked(final_episode, "final_episode", B);
            out.episode_index = checked(episode_index, "episode_index", B);
            out.collision_kind = optional_checked<int8_t>(collision_kind, "collision_kind", B);
            nb::gil_scoped_release release;
            return self.world->step(a, &out);
          },
          "actions"_a, "reward"_a.noconvert(), "terminated"_a.noconvert(), "truncated"_a.noconvert(),
          "outcome"_a.noconvert(), "final_dmin"_a.noconvert(), "final_episode"_a.noconvert(),
          "episode_index"_a.noconvert(), "collision_kind"_a.none() = nb::none(),
          "Advance every running episode by one step and write its per-slot report (reward; terminated, "
          "truncated, final status, dmin, episode index and collision kind where an episode ended); returns "
          "the number of episodes that ended.")
      .def(
          "route_state",
          [](PyWorld& self, int slot) {
            std::vector<double> state = self.world->route_state(slot);
            return state;
          },
          "slot"_a, "With human_routes: the route state of one slot's humans (a list of floats) for set_route_state.")
      .def(
          "set_route_state",
          [](PyWorld& self, int slot, Array<double> state) {
            self.world->set_route_state(slot, state.data(), state.size());
          },
          "slot"_a, "state"_a, "Puts back one slot's route state (route_state's).")
      .def(
          "set_obstacles",
          [](PyWorld& self, int slot, Array<double> vertices, Array<int64_t> offsets) {
            const int P = polygon_count(vertices, offsets);
            self.world->set_obstacles(slot, vertices.data(), offsets.data(), P);
          },
          "slot"_a, "vertices"_a, "offsets"_a,
          "Sets the static obstacles of one slot from flat polygons (StaticMap.to_flat); they stay for the "
          "slot's later episodes until set again. Raises ValueError beyond max_obstacle_vertices.")
      .def(
          "refill_done",
          [](PyWorld& self, const socialnav::ScenarioConfig& scenario, Array<int64_t> indices, Array<int64_t> seeds,
             Array<int64_t> episode_index, Array<int64_t> episode_seed, Array<int32_t> failure, nb::object observation,
             nb::object final_observation) {
            const auto& c = self.world->config();
            check_fits(scenario, c);
            const size_t B = static_cast<size_t>(c.batch);
            const size_t count = indices.size();
            if (count > B) throw std::invalid_argument("more indices than slots: " + std::to_string(count));
            checked(seeds, "seeds", count);
            int64_t* index = checked(episode_index, "episode_index", B);
            int64_t* seed = checked(episode_seed, "episode_seed", B);
            int32_t* f = checked(failure, "failure", B);
            size_t done = 0;  // the final observation's rows
            if (!final_observation.is_none())
              for (size_t b = 0; b < B; ++b) done += self.world->buffers().done[b] != 0;
            socialnav::ObservationBuffers obs{}, final_obs{};
            const int beams = self.world->sensing().lidar_beams;
            const bool with_obs = observation_buffers(observation, "observation", B, c.agents - 1, beams, obs);
            const bool with_final =
                observation_buffers(final_observation, "final_observation", done, c.agents - 1, beams, final_obs);
            nb::gil_scoped_release release;
            return self.world->refill_done(scenario, indices.data(), seeds.data(), static_cast<int>(count), index, seed,
                                           f, with_obs ? &obs : nullptr, with_final ? &final_obs : nullptr);
          },
          "scenario"_a, "indices"_a, "seeds"_a, "episode_index"_a.noconvert(), "episode_seed"_a.noconvert(),
          "failure"_a.noconvert(), "observation"_a.none() = nb::none(), "final_observation"_a.none() = nb::none(),
          "Refills the slots whose episode ended in the last step, in slot order, with the episodes indices "
          "(seeds: theirs) of a built-in scenario; ended slots beyond them go idle. failure (B,) holds the codes of "
          "the first refilled ones; returns how many failed. "
          "observation: (robot, humans, human_mask, active, time) arrays of B rows for observe's result "
          "afterwards; final_observation: the same with one row per ended slot (slot order), their "
          "observation before the refill; both written in the same pass.")
      .def(
          "give_human_velocities",
          [](PyWorld& self, nb::object velocity) {
            const auto& c = self.world->config();
            if (!self.world->takes_given_velocities())
              throw std::invalid_argument("this world's humans follow the native behaviour '" + c.human_behaviour +
                                          "'");
            double* v = optional_checked<double>(velocity, "velocity", static_cast<size_t>(c.batch) * c.agents * 2);
            self.world->give_human_velocities(v);
            self.given_velocity = velocity;  // kept alive while the world reads it
          },
          "velocity"_a.none(),
          "For a world built with human_behaviour '': the array (B, A, 2) the humans' velocities of each step "
          "(and preview) are read from; the caller writes it before each call (None: none given).")
      .def(
          "preview_humans",
          [](PyWorld& self, Array<double> out) {
            const auto& c = self.world->config();
            double* o = checked(out, "out", static_cast<size_t>(c.batch) * (c.agents - 1) * socialnav::kHumanFeatures);
            nb::gil_scoped_release release;
            self.world->preview_humans(o);
          },
          "out"_a.noconvert(), "The humans' exact next states (B, N, 5) without stepping.")
      .def(
          "load_generated",
          [](PyWorld& self, const socialnav::ScenarioConfig& scenario, Array<int64_t> slots, Array<int64_t> seeds,
             Array<int32_t> failure) {
            const auto& c = self.world->config();
            check_fits(scenario, c);
            const size_t k = slots.size();
            checked(seeds, "seeds", k);
            int32_t* f = checked(failure, "failure", k);
            std::vector<bool> seen(static_cast<size_t>(c.batch), false);
            for (size_t i = 0; i < k; ++i) {
              const int64_t b = slots.data()[i];
              if (b < 0 || b >= c.batch) throw std::invalid_argument("slot " + std::to_string(b) + " out of range");
              if (seen[static_cast<size_t>(b)])  // two threads would write the same slot
                throw std::invalid_argument("slot " + std::to_string(b) + " given twice");
              seen[static_cast<size_t>(b)] = true;
            }
            nb::gil_scoped_release release;
            self.world->load_generated(scenario, slots.data(), seeds.data(), static_cast<int>(k), f);
          },
          "scenario"_a, "slots"_a, "seeds"_a, "failure"_a.noconvert(),
          "Generates the episodes of seeds (a built-in scenario) straight into slots and starts them; "
          "failure[i] as generate_humans (a failed slot is left idle).")
      .def(
          "observe",
          [](PyWorld& self, Array<double> robot, Array<double> humans, Array<bool> human_mask, Array<bool> active,
             Array<double> time, nb::object lidar) {
            const auto& c = self.world->config();
            const size_t B = static_cast<size_t>(c.batch), N = static_cast<size_t>(c.agents - 1);
            double* r = checked(robot, "robot", B * socialnav::kRobotFeatures);
            double* h = checked(humans, "humans", B * N * socialnav::kHumanFeatures);
            auto* m = reinterpret_cast<uint8_t*>(checked(human_mask, "human_mask", B * N));
            auto* a = reinterpret_cast<uint8_t*>(checked(active, "active", B));
            double* t = checked(time, "time", B);
            const int beams = self.world->sensing().lidar_beams;
            float* l = optional_checked<float>(lidar, "lidar", B * static_cast<size_t>(beams));
            if (l && beams == 0) throw std::invalid_argument("lidar: this world has no lidar (set_sensing)");
            nb::gil_scoped_release release;
            self.world->observe(socialnav::ObservationBuffers{r, h, m, a, t, l});
          },
          "robot"_a.noconvert(), "humans"_a.noconvert(), "human_mask"_a.noconvert(), "active"_a.noconvert(),
          "time"_a.noconvert(), "lidar"_a.none() = nb::none(),
          "The observation of every slot, written into the given arrays (lidar: (B, beams) float32 with a lidar).")
      .def(
          "set_sensing",
          [](PyWorld& self, const socialnav::SensingConfig& sensing, Array<int64_t> episode_seed) {
            const int64_t* seeds =
                checked(episode_seed, "episode_seed", static_cast<size_t>(self.world->config().batch));
            self.world->set_sensing(sensing, seeds);
            self.episode_seed = nb::cast(episode_seed);  // kept alive while the world reads it
          },
          "sensing"_a, "episode_seed"_a.noconvert(),
          "The robot's perception (SensingConfig); episode_seed (B,) keys its noise and dropout (read, not copied).")
      .def(
          "sensing_state", [](PyWorld& self, int slot) { return self.world->sensing_state(slot); }, "slot"_a,
          "With latency: one slot's record of past states (a list of floats) for set_sensing_state.")
      .def(
          "set_sensing_state",
          [](PyWorld& self, int slot, Array<double> state) {
            self.world->set_sensing_state(slot, state.data(), state.size());
          },
          "slot"_a, "state"_a, "Puts back one slot's sensing state (sensing_state's).")
      .def(
          "robot_twist",
          [](PyWorld& self, Array<double> out, bool new_at_rest) {
            const socialnav::World& w = *self.world;
            const int B = w.config().batch;
            double* o = checked(out, "out", static_cast<size_t>(B) * 2);
            for (int b = 0; b < B; ++b) {
              const socialnav::Vec2 twist = w.robot_twist(b, new_at_rest);
              o[2 * b] = twist.x;
              o[2 * b + 1] = twist.y;
            }
          },
          "out"_a.noconvert(), "new_at_rest"_a = true,
          "A differential-drive robot's (v [m/s], omega [rad/s]) of the last step, written into out (B, 2); "
          "new_at_rest: (0, 0) in slots whose episode has not stepped yet (false: what the slot last drove).")
      .def(
          "set_robot_twist",
          [](PyWorld& self, int slot, double v, double omega) { self.world->set_robot_twist(slot, v, omega); },
          "slot"_a, "v"_a, "omega"_a, "Puts back one slot's differential-drive (v, omega) (robot_twist's).");

  nb::class_<socialnav::PreparedObstacleBatch>(m, "PreparedObstacleBatch")
      .def(
          "__init__",
          [](socialnav::PreparedObstacleBatch* self, Array<double> vertices, Array<int64_t> polygon_offsets,
             Array<int64_t> episode_polygons) {
            if (episode_polygons.size() < 1) throw std::invalid_argument("episode_polygons must have B + 1 entries");
            new (self) socialnav::PreparedObstacleBatch(
                prepare_batch(vertices, polygon_offsets, episode_polygons, episode_polygons.size() - 1));
          },
          "vertices"_a, "polygon_offsets"_a, "episode_polygons"_a,
          "The static maps of B episodes prepared once for the native robot policies: vertices (V, 2), "
          "polygon_offsets (P + 1,), episode_polygons (B + 1,).")
      .def_prop_ro("episodes", [](const socialnav::PreparedObstacleBatch& self) { return self.first.size(); })
      .def_prop_ro(
          "prepared_vertices", [](const socialnav::PreparedObstacleBatch& self) { return self.vertex.size(); },
          "Vertices stored (episodes with the previous episode's map share its copy).");

  nb::class_<socialnav::ThreadPool>(m, "ThreadPool")
      .def(nb::init<int>(), "threads"_a)
      .def_prop_ro("size", &socialnav::ThreadPool::size);
  // A forked child leaks the pools it inherited on purpose (sim/pool.py: their threads do not exist
  // there); without this, nanobind reports them as reference leaks when the child exits.
  m.def("_silence_leak_warnings", []() { nb::set_leak_warnings(false); });

  nb::class_<socialnav::SarlScorer>(m, "SarlScorer")
      .def(
          "__init__",
          [](socialnav::SarlScorer* self, nb::list mlp1, nb::list mlp2, nb::list attention, nb::list global_term,
             nb::list mlp3, int self_dim, const std::string& kernel_name) {
            const socialnav::ScorerKernel kernel = socialnav::resolve_kernel(kernel_name);
            // Each layer: (weight (out, in), bias (out)) float32 C-contiguous arrays, PyTorch's layout.
            auto layers = [kernel](nb::list items, const char* name) {
              std::vector<socialnav::DenseLayer> out;
              for (size_t i = 0; i < nb::len(items); ++i) {
                nb::tuple t = nb::cast<nb::tuple>(items[i]);
                if (nb::len(t) != 2) throw std::invalid_argument(std::string(name) + ": each layer is (weight, bias)");
                auto w = nb::cast<Array<float>>(t[0], false);
                auto b = nb::cast<Array<float>>(t[1], false);
                if (w.ndim() != 2 || b.ndim() != 1 || b.shape(0) != w.shape(0))
                  throw std::invalid_argument(std::string(name) + " layer " + std::to_string(i) +
                                              ": expected weight (out, in) and bias (out)");
                out.emplace_back(w.data(), b.data(), static_cast<int>(w.shape(0)), static_cast<int>(w.shape(1)),
                                 kernel);
              }
              return out;
            };
            new (self) socialnav::SarlScorer(layers(mlp1, "mlp1"), layers(mlp2, "mlp2"), layers(attention, "attention"),
                                             layers(global_term, "global_term"), layers(mlp3, "mlp3"), self_dim);
          },
          "mlp1"_a, "mlp2"_a, "attention"_a, "global_term"_a, "mlp3"_a, "self_dim"_a, "kernel"_a = "auto")
      .def_static("supported", &socialnav::SarlScorer::supported)
      .def_static(
          "kernel_supported",
          [](const std::string& name) {
            if (name == "avx2") return socialnav::kernel_supported(socialnav::ScorerKernel::avx2);
            if (name == "avx512") return socialnav::kernel_supported(socialnav::ScorerKernel::avx512);
            throw std::invalid_argument("unknown kernel '" + name + "' (expected avx2 or avx512)");
          },
          "kernel"_a, "Whether this CPU runs the named vector kernel.")
      .def_prop_ro("kernel", [](const socialnav::SarlScorer& self) { return socialnav::kernel_name(self.kernel()); })
      .def_prop_ro("input_dim", &socialnav::SarlScorer::input_dim)
      .def(
          "values",
          [](const socialnav::SarlScorer& self, Array<float> joint, Array<bool> mask, Array<float> out,
             socialnav::ThreadPool& pool, int states_per_tile) {
            if (joint.ndim() != 3 || static_cast<int>(joint.shape(2)) != self.input_dim())
              throw std::invalid_argument("joint must be (M, N, " + std::to_string(self.input_dim()) + ")");
            const size_t M = joint.shape(0), N = joint.shape(1);
            if (N < 1) throw std::invalid_argument("joint: N must be >= 1");
            checked(mask, "mask", M * N);
            float* o = checked(out, "out", M);
            const float* j = joint.data();
            const auto* mk = reinterpret_cast<const uint8_t*>(mask.data());
            nb::gil_scoped_release release;
            self.values(j, mk, static_cast<int64_t>(M), static_cast<int>(N), o, pool, states_per_tile);
          },
          "joint"_a.noconvert(), "mask"_a.noconvert(), "out"_a.noconvert(), "pool"_a, "states_per_tile"_a = 32,
          "SARL values of M joint states, written into out (M,).");

  m.def(
      "robot_actions",
      [](const std::string& policy, Array<double> robot, Array<double> humans, Array<bool> mask, Array<bool> active,
         int kinematics, double rotation_limit, double dt, nb::object orca, double safety_space,
         nb::object social_force, socialnav::ThreadPool& pool, Array<double> out, nb::object obstacles,
         double route_clearance, double max_reverse_speed) {
        if (robot.ndim() != 2 || robot.shape(1) != socialnav::kRobotFeatures)
          throw std::invalid_argument("robot must be (B, " + std::to_string(socialnav::kRobotFeatures) + ")");
        const size_t B = robot.shape(0);
        if (humans.ndim() != 3 || humans.shape(0) != B || humans.shape(2) != socialnav::kHumanFeatures)
          throw std::invalid_argument("humans must be (B, N, " + std::to_string(socialnav::kHumanFeatures) + ")");
        const size_t N = humans.shape(1);
        checked(mask, "mask", B * N);
        checked(active, "active", B);
        double* o = checked(out, "out", B * 2);
        const socialnav::ObservationView obs{static_cast<int>(B),
                                             static_cast<int>(N),
                                             robot.data(),
                                             humans.data(),
                                             reinterpret_cast<const uint8_t*>(mask.data()),
                                             reinterpret_cast<const uint8_t*>(active.data())};
        const socialnav::ActionFormat format{kinematics, rotation_limit, max_reverse_speed};
        const socialnav::ObstacleBatchView wall_view = batch_walls(obstacles, B, "the observation has ");
        const socialnav::OrcaValues orca_values = socialnav::orca_values(behaviour_values("orca", orca));
        const socialnav::SocialForceParams sf_values =
            socialnav::social_force_values(behaviour_values("social_force", social_force));
        nb::gil_scoped_release release;
        socialnav::robot_actions(policy, obs, format, dt, orca_values, safety_space, sf_values, pool, o, wall_view,
                                 route_clearance);
      },
      "policy"_a, "robot"_a, "humans"_a, "mask"_a, "active"_a, "kinematics"_a, "rotation_limit"_a, "dt"_a,
      "orca"_a.none(), "safety_space"_a, "social_force"_a.none(), "pool"_a, "out"_a.noconvert(),
      "obstacles"_a.none() = nb::none(), "route_clearance"_a = 0.1, "max_reverse_speed"_a = 0.0,
      "Batched actions of a native robot policy ('linear', 'orca', 'orca_route', 'social_force' or "
      "'social_force_route'), written into out (B, 2). route_clearance [m]: the '_route' policies' clearance "
      "from the walls beyond their radius. "
      "orca, social_force: the humans' behaviour parameters of that name (a dict by name, the values in "
      "declared order, or None for the defaults); safety_space [m]: the ORCA robot's own inflation. obstacles: "
      "None or the B episodes' static maps as PreparedObstacleBatch.");

  m.def(
      "robot_route_goals",
      [](Array<double> robot, nb::object obstacles, double route_clearance, Array<double> out) {
        if (robot.ndim() != 2 || robot.shape(1) != socialnav::kRobotFeatures)
          throw std::invalid_argument("robot must be (B, " + std::to_string(socialnav::kRobotFeatures) + ")");
        if (!(route_clearance >= 0.0)) throw std::invalid_argument("route_clearance must be >= 0");
        const size_t B = robot.shape(0);
        double* o = checked(out, "out", B * 2);
        const socialnav::ObstacleBatchView wall_view = batch_walls(obstacles, B, "the robot rows are ");
        nb::gil_scoped_release release;
        socialnav::robot_route_goals(robot.data(), static_cast<int>(B), wall_view, route_clearance, o);
      },
      "robot"_a.noconvert(), "obstacles"_a.none(), "route_clearance"_a, "out"_a.noconvert(),
      "The point each robot's route around the walls heads for (the goal on an open floor or in sight), written "
      "into out (B, 2): robot (B, 9) rows, obstacles None or the B episodes' PreparedObstacleBatch, "
      "route_clearance [m] kept from the walls beyond the robot's radius.");

  using SC = socialnav::ScenarioConfig;
  nb::class_<SC>(m, "ScenarioConfig")
      .def(nb::init<>())
      .def_rw("kind", &SC::kind)
      .def_rw("n_humans", &SC::n_humans)
      .def_rw("salt_prefix", &SC::salt_prefix)
      .def_rw("robot_radius", &SC::robot_radius)
      .def_rw("robot_v_pref", &SC::robot_v_pref)
      .def_rw("human_radius", &SC::human_radius)
      .def_rw("human_v_pref", &SC::human_v_pref)
      .def_rw("randomize_attributes", &SC::randomize_attributes)
      .def_rw("v_pref_low", &SC::v_pref_low)
      .def_rw("v_pref_high", &SC::v_pref_high)
      .def_rw("radius_low", &SC::radius_low)
      .def_rw("radius_high", &SC::radius_high)
      .def_rw("discomfort_dist", &SC::discomfort_dist)
      .def_rw("circle_radius", &SC::circle_radius)
      .def_rw("max_attempts", &SC::max_attempts)
      .def_rw("start_noise", &SC::start_noise)
      .def_rw("square_width", &SC::square_width)
      .def_rw("flow_axis", &SC::flow_axis)
      .def_rw("band", &SC::band)
      .def_rw("band_width", &SC::band_width);
  m.attr("SCENARIO_CIRCLE") = static_cast<int>(socialnav::SCENARIO_CIRCLE);
  m.attr("SCENARIO_RANDOM") = static_cast<int>(socialnav::SCENARIO_RANDOM);
  m.attr("SCENARIO_TRAFFIC") = static_cast<int>(socialnav::SCENARIO_TRAFFIC);
  m.attr("SCENARIO_SQUARE_CROSSING") = static_cast<int>(socialnav::SCENARIO_SQUARE_CROSSING);

  m.def(
      "generate_humans",
      [](const SC& config, Array<int64_t> seeds, Array<double> start, Array<double> goal, Array<double> radius,
         Array<double> v_pref, Array<int32_t> failure) {
        if (config.kind < socialnav::SCENARIO_CIRCLE || config.kind > socialnav::SCENARIO_SQUARE_CROSSING)
          throw std::invalid_argument("unknown scenario kind " + std::to_string(config.kind));
        if (config.n_humans < 0 || config.max_attempts < 1 || (config.flow_axis != 0 && config.flow_axis != 1))
          throw std::invalid_argument("invalid scenario config (n_humans, max_attempts or flow_axis)");
        const size_t B = seeds.size(), N = static_cast<size_t>(config.n_humans);
        double* s = checked(start, "start", B * N * 2);
        double* g = checked(goal, "goal", B * N * 2);
        double* r = checked(radius, "radius", B * N);
        double* v = checked(v_pref, "v_pref", B * N);
        int32_t* f = checked(failure, "failure", B);
        const int64_t* sd = seeds.data();
        nb::gil_scoped_release release;
        for (size_t b = 0; b < B; ++b)
          f[b] = socialnav::generate_humans(config, sd[b], s + 2 * N * b, g + 2 * N * b, r + N * b, v + N * b);
      },
      "config"_a, "seeds"_a, "start"_a.noconvert(), "goal"_a.noconvert(), "radius"_a.noconvert(),
      "v_pref"_a.noconvert(), "failure"_a.noconvert(),
      "Humans of B episodes of a built-in scenario, bit-identical to its Python generator; failure[b] is "
      "0, or 1 + 2j / 2 + 2j when the start / goal of human j found no clear position.");

  m.def(
      "orca_velocity",
      [](Array<double> position, Array<double> velocity, double radius, double max_speed, Array<double> pref_velocity,
         Array<double> neighbor_positions, Array<double> neighbor_velocities, Array<double> neighbor_radii,
         double time_horizon, double time_step, double neighbor_dist, int max_neighbors) {
        const size_t n = neighbor_radii.size();
        if (neighbor_positions.size() != 2 * n || neighbor_velocities.size() != 2 * n)
          throw std::invalid_argument("neighbour arrays must be (K, 2), (K, 2) and (K,)");
        if (max_neighbors < 0 || max_neighbors > socialnav::kMaxOrcaNeighbors)
          throw std::invalid_argument("max_neighbors out of range");
        std::vector<socialnav::OrcaNeighbor> candidates(n);
        for (size_t k = 0; k < n; ++k)
          candidates[k] = socialnav::OrcaNeighbor{
              Vec2{neighbor_positions.data()[2 * k], neighbor_positions.data()[2 * k + 1]},
              Vec2{neighbor_velocities.data()[2 * k], neighbor_velocities.data()[2 * k + 1]}, neighbor_radii.data()[k]};
        socialnav::OrcaParams params;
        params.neighbor_dist = neighbor_dist;
        params.max_neighbors = max_neighbors;
        params.time_horizon = time_horizon;
        socialnav::OrcaScratch scratch;
        const socialnav::OrcaAgent self{vec(position), vec(velocity), radius, max_speed, vec(pref_velocity)};
        const Vec2 v = socialnav::orca_new_velocity_select(self, candidates.data(), static_cast<int>(n), params,
                                                           time_step, scratch);
        return nb::make_tuple(v.x, v.y);
      },
      "position"_a, "velocity"_a, "radius"_a, "max_speed"_a, "pref_velocity"_a, "neighbor_positions"_a,
      "neighbor_velocities"_a, "neighbor_radii"_a, "time_horizon"_a = 5.0, "time_step"_a = 0.25,
      "neighbor_dist"_a = 10.0, "max_neighbors"_a = 10,
      "New velocity of one agent under ORCA (RVO2 semantics, no obstacles).");

  m.def(
      "social_force_velocity",
      [](Array<double> position, Array<double> velocity, Array<double> desired_velocity, double max_speed,
         Array<double> other_positions, Array<double> other_velocities, nb::object params_given, double dt) {
        const socialnav::SocialForceParams params =
            socialnav::social_force_values(behaviour_values("social_force", params_given));
        const size_t n = other_positions.size() / 2;
        std::vector<socialnav::SocialForceOther> others(n);
        for (size_t k = 0; k < n; ++k)
          others[k] =
              socialnav::SocialForceOther{Vec2{other_positions.data()[2 * k], other_positions.data()[2 * k + 1]},
                                          Vec2{other_velocities.data()[2 * k], other_velocities.data()[2 * k + 1]}};
        const socialnav::SocialForceAgent self{vec(position), vec(velocity), vec(desired_velocity), max_speed};
        const Vec2 v = socialnav::social_force_new_velocity(self, others.data(), static_cast<int>(n), params, dt);
        return nb::make_tuple(v.x, v.y);
      },
      "position"_a, "velocity"_a, "desired_velocity"_a, "max_speed"_a, "other_positions"_a, "other_velocities"_a,
      "params"_a.none() = nb::none(), "dt"_a = 0.25,
      "New velocity of one agent under the social force model (params: the social_force behaviour's, a dict by "
      "name or None for the defaults).");

  m.def(
      "orca_step",
      [](Array<double> positions, Array<double> velocities, Array<double> pref_velocities, Array<double> radii,
         Array<double> max_speeds, nb::object params_given, double time_step, Array<double> obstacle_vertices,
         Array<int64_t> obstacle_offsets, Array<double> out) {
        const socialnav::OrcaParams params = socialnav::orca_values(behaviour_values("orca", params_given)).solver;
        const size_t n = radii.size();
        checked(positions, "positions", 2 * n);
        checked(velocities, "velocities", 2 * n);
        checked(pref_velocities, "pref_velocities", 2 * n);
        checked(max_speeds, "max_speeds", n);
        double* o = checked(out, "out", 2 * n);
        const int P = polygon_count(obstacle_vertices, obstacle_offsets);
        const socialnav::PreparedObstacles walls =
            socialnav::prepare_obstacles(obstacle_vertices.data(), obstacle_offsets.data(), P);
        const double *p = positions.data(), *v = velocities.data(), *pv = pref_velocities.data();
        const double *r = radii.data(), *ms = max_speeds.data();
        nb::gil_scoped_release release;
        socialnav::orca_step_agents(static_cast<int>(n), p, v, pv, r, ms, params, time_step, walls.orca_view(), o);
      },
      "positions"_a, "velocities"_a, "pref_velocities"_a, "radii"_a, "max_speeds"_a, "params"_a.none(), "time_step"_a,
      "obstacle_vertices"_a, "obstacle_offsets"_a, "out"_a.noconvert(),
      "New velocities (n, 2) of n agents after one ORCA step with static obstacles (RVO2's computeNeighbors "
      "and computeNewVelocity for every agent; positions are not advanced). params: the orca behaviour's (a dict "
      "by name, e.g. neighbor_dist, max_neighbors, time_horizon, time_horizon_obst; None: the defaults); radii "
      "are used as given.");

  m.def(
      "social_force_wall_force",
      [](Array<double> position, Array<double> obstacle_vertices, Array<int64_t> obstacle_offsets,
         nb::object params_given) {
        const socialnav::SocialForceParams params =
            socialnav::social_force_values(behaviour_values("social_force", params_given));
        const int P = polygon_count(obstacle_vertices, obstacle_offsets);
        const socialnav::PreparedObstacles walls =
            socialnav::prepare_obstacles(obstacle_vertices.data(), obstacle_offsets.data(), P);
        const Vec2 f = socialnav::social_force_wall_repulsion(vec(position), walls.view(), params);
        return nb::make_tuple(f.x, f.y);
      },
      "position"_a, "obstacle_vertices"_a, "obstacle_offsets"_a, "params"_a.none() = nb::none(),
      "Helbing & Molnar's wall repulsion on an agent at position (sum over the obstacles).");

  m.def(
      "swept_obstacle_clearance",
      [](Array<double> start, Array<double> end, double radius, Array<double> obstacle_vertices,
         Array<int64_t> obstacle_offsets) {
        const int P = polygon_count(obstacle_vertices, obstacle_offsets);
        const socialnav::PreparedObstacles walls =
            socialnav::prepare_obstacles(obstacle_vertices.data(), obstacle_offsets.data(), P);
        return socialnav::swept_obstacle_clearance(walls.view(), vec(start), vec(end), radius);
      },
      "start"_a, "end"_a, "radius"_a, "obstacle_vertices"_a, "obstacle_offsets"_a,
      "Clearance of a disc moving from start to end against the obstacles (< 0: it touched one).");

  m.def(
      "swept_disc_hits_obstacles",
      [](Array<double> start, Array<double> end, double radius, Array<double> obstacle_vertices,
         Array<int64_t> obstacle_offsets) {
        const int P = polygon_count(obstacle_vertices, obstacle_offsets);
        const socialnav::PreparedObstacles walls =
            socialnav::prepare_obstacles(obstacle_vertices.data(), obstacle_offsets.data(), P);
        return socialnav::swept_disc_hits_obstacles(walls.view(), vec(start), vec(end), radius);
      },
      "start"_a, "end"_a, "radius"_a, "obstacle_vertices"_a, "obstacle_offsets"_a,
      "The world's collision test: swept_obstacle_clearance(...) < 0, with culling and an early exit.");

  m.def(
      "orca_obstacle_lines",
      [](Array<double> position, Array<double> velocity, double radius, double max_speed,
         Array<double> obstacle_vertices, Array<int64_t> obstacle_offsets, double time_horizon_obst) {
        const int P = polygon_count(obstacle_vertices, obstacle_offsets);
        const socialnav::PreparedObstacles walls =
            socialnav::prepare_obstacles(obstacle_vertices.data(), obstacle_offsets.data(), P);
        socialnav::OrcaScratch scratch;
        const socialnav::OrcaAgent self{vec(position), vec(velocity), radius, max_speed, Vec2{}};
        const int k = socialnav::orca_obstacle_lines(self, walls.orca_view(), time_horizon_obst, scratch);
        nb::list out;
        for (int i = 0; i < k; ++i) {
          const socialnav::Line& l = scratch.lines[i];
          out.append(nb::make_tuple(l.point.x, l.point.y, l.direction.x, l.direction.y));
        }
        return out;
      },
      "position"_a, "velocity"_a, "radius"_a, "max_speed"_a, "obstacle_vertices"_a, "obstacle_offsets"_a,
      "time_horizon_obst"_a = 5.0,
      "The obstacle ORCA half-planes (px, py, dx, dy; permitted on the left) of one agent, in solver order.");

  m.def(
      "orca_obstacle_neighbors",
      [](Array<double> position, double radius, double max_speed, Array<double> obstacle_vertices,
         Array<int64_t> obstacle_offsets, double time_horizon_obst) {
        const int P = polygon_count(obstacle_vertices, obstacle_offsets);
        const socialnav::PreparedObstacles walls =
            socialnav::prepare_obstacles(obstacle_vertices.data(), obstacle_offsets.data(), P);
        socialnav::OrcaScratch scratch;
        const socialnav::OrcaAgent self{vec(position), Vec2{}, radius, max_speed, Vec2{}};
        socialnav::orca_obstacle_lines(self, walls.orca_view(), time_horizon_obst, scratch);
        nb::list neighbors;
        for (int i = 0; i < scratch.obstacle_count; ++i) neighbors.append(scratch.obstacle_index[i]);
        nb::list vertices;
        for (size_t i = 0; i < walls.orca.vertex.size(); ++i) {
          const socialnav::ObstacleVertex& v = walls.orca.vertex[i];
          vertices.append(nb::make_tuple(v.point.x, v.point.y, v.next, v.prev, v.convex, walls.orca.parent[i],
                                         walls.orca.is_left[i] != 0, walls.orca.depth[i]));
        }
        return nb::make_tuple(neighbors, vertices);
      },
      "position"_a, "radius"_a, "max_speed"_a, "obstacle_vertices"_a, "obstacle_offsets"_a, "time_horizon_obst"_a = 5.0,
      "RVO2's obstacle neighbours of one agent (vertex ids, nearest first, ties in RVO2's tree-query order) and "
      "the map as ORCA sees it: (x, y, next, prev, convex, tree parent, is left child, depth) per vertex, the split "
      "points after the map's own "
      "vertices (RVO2's obstacle ids).");

  m.def(
      "plan_route",
      [](Array<double> start, Array<double> goal, double radius, double clearance, Array<double> obstacle_vertices,
         Array<int64_t> obstacle_offsets) {
        if (!(radius > 0.0) || !(clearance >= 0.0) || !std::isfinite(radius) || !std::isfinite(clearance))
          throw std::invalid_argument("plan_route: radius must be > 0 and clearance >= 0 (finite), got " +
                                      std::to_string(radius) + " and " + std::to_string(clearance));
        const int P = polygon_count(obstacle_vertices, obstacle_offsets);
        const socialnav::PreparedObstacles walls =
            socialnav::prepare_obstacles(obstacle_vertices.data(), obstacle_offsets.data(), P);
        socialnav::Route route;
        if (P == 0) {
          route.point.assign(1, vec(goal));
          route.found = true;
          route.inflation = radius;
        } else {
          nb::gil_scoped_release release;
          socialnav::plan_route(walls.view(), vec(start), vec(goal), radius, clearance, route);
        }
        nb::list points;
        for (const Vec2& p : route.point) points.append(nb::make_tuple(p.x, p.y));
        return nb::make_tuple(points, route.found, route.inflation);
      },
      "start"_a, "goal"_a, "radius"_a, "clearance"_a, "obstacle_vertices"_a, "obstacle_offsets"_a,
      "The shortest route (routes.hpp) of an agent of radius [m] from start to goal keeping clearance [m] from the "
      "walls where it can: (points, found, inflation), the points to pass with the goal last; found False: no "
      "route at any inflation (points: the goal alone).");

  m.def(
      "plan_route_around",
      [](Array<double> start, Array<double> goal, double radius, double clearance, Array<double> obstacle_vertices,
         Array<int64_t> obstacle_offsets, Array<double> centres, Array<double> radii) {
        if (!(radius > 0.0) || !(clearance >= 0.0) || !std::isfinite(radius) || !std::isfinite(clearance))
          throw std::invalid_argument("plan_route_around: radius must be > 0 and clearance >= 0 (finite), got " +
                                      std::to_string(radius) + " and " + std::to_string(clearance));
        const int P = polygon_count(obstacle_vertices, obstacle_offsets);
        const int n = static_cast<int>(radii.shape(0));
        checked(centres, "centres", 2 * static_cast<size_t>(n));
        std::vector<Vec2> c(static_cast<size_t>(n));
        for (int k = 0; k < n; ++k) c[k] = Vec2{centres.data()[2 * k], centres.data()[2 * k + 1]};
        const socialnav::PreparedObstacles walls =
            socialnav::prepare_obstacles(obstacle_vertices.data(), obstacle_offsets.data(), P);
        socialnav::Route route;
        {
          nb::gil_scoped_release release;
          socialnav::plan_route_around(walls.view(), c.data(), radii.data(), n, vec(start), vec(goal), radius,
                                       clearance, route);
        }
        nb::list points;
        for (const Vec2& p : route.point) points.append(nb::make_tuple(p.x, p.y));
        return nb::make_tuple(points, route.found, route.inflation);
      },
      "start"_a, "goal"_a, "radius"_a, "clearance"_a, "obstacle_vertices"_a, "obstacle_offsets"_a, "centres"_a,
      "radii"_a,
      "plan_route among the walls and n standing discs (centres (n, 2), radii (n,)), each taken as the regular "
      "octagon around it: the route-following robot policies' planner (routes.hpp, plan_route_around).");

  m.def(
      "route_graph_around_matches",
      [](Array<double> obstacle_vertices, Array<int64_t> obstacle_offsets, Array<double> centres, Array<double> radii,
         double inflation) {
        const int P = polygon_count(obstacle_vertices, obstacle_offsets);
        const int n = static_cast<int>(radii.shape(0));
        checked(centres, "centres", 2 * static_cast<size_t>(n));
        if (P == 0 || n == 0 || !(inflation > 0.0))
          throw std::invalid_argument("route_graph_around_matches: a map, discs and an inflation > 0");
        std::vector<Vec2> c(static_cast<size_t>(n));
        for (int k = 0; k < n; ++k) c[k] = Vec2{centres.data()[2 * k], centres.data()[2 * k + 1]};
        const socialnav::PreparedObstacles walls =
            socialnav::prepare_obstacles(obstacle_vertices.data(), obstacle_offsets.data(), P);
        return socialnav::route_graph_around_matches(walls.view(), c.data(), radii.data(), n, inflation);
      },
      "obstacle_vertices"_a, "obstacle_offsets"_a, "centres"_a, "radii"_a, "inflation"_a,
      "Whether plan_route_around's graph (the walls' cached graph with the discs' octagons added) equals the full "
      "build over the walls and the octagons, bit for bit (tests).");

  m.def(
      "route_kernel_values",
      [](Array<double> a, Array<double> b, double c, Array<double> obstacle_vertices, Array<int64_t> obstacle_offsets,
         bool baseline) {
        checked(a, "a", 2);
        checked(b, "b", 2);
        const int P = polygon_count(obstacle_vertices, obstacle_offsets);
        const socialnav::PreparedObstacles walls =
            socialnav::prepare_obstacles(obstacle_vertices.data(), obstacle_offsets.data(), P);
        const socialnav::EdgeSet edges = socialnav::compact_edges(walls.view());
        const std::array<double, 6> v = socialnav::route_kernel_values(edges, vec(a), vec(b), c, baseline);
        return nb::make_tuple(v[0], v[1], v[2], v[3], v[4], v[5] != 0.0);
      },
      "a"_a, "b"_a, "c"_a, "obstacle_vertices"_a, "obstacle_offsets"_a, "baseline"_a = false,
      "What the route kernels give for the segment [a, b] over the map's edges (tests): squared distances of the "
      "segment, of a and of b, the segment's again from the kernel without the ends, a's from the point kernel, and "
      "whether the segment's clearance is >= c; from the build this CPU dispatches to (x86-64-v4, AVX2 or the "
      "baseline), or with baseline=True from the baseline build.");
  m.def(
      "route_kernel_build", [] { return std::string(socialnav::avx512_clone_build()); },
      "The build of the route kernels this CPU runs: 'x86-64-v4', 'avx2' or 'baseline'.");

  m.def(
      "route_distances",
      [](Array<double> points, Array<double> goal, double radius, Array<double> obstacle_vertices,
         Array<int64_t> obstacle_offsets, Array<double> out) {
        if (!(radius > 0.0) || !std::isfinite(radius))
          throw std::invalid_argument("route_distances: radius must be finite and > 0, got " + std::to_string(radius));
        const size_t n = out.size();
        checked(points, "points", 2 * n);
        checked(goal, "goal", 2);
        double* o = checked(out, "out", n);
        const int P = polygon_count(obstacle_vertices, obstacle_offsets);
        const socialnav::PreparedObstacles walls =
            socialnav::prepare_obstacles(obstacle_vertices.data(), obstacle_offsets.data(), P);
        static_assert(sizeof(Vec2) == 2 * sizeof(double), "points (n, 2) are read as n Vec2");
        const auto* pts = reinterpret_cast<const Vec2*>(points.data());
        const Vec2 g = vec(goal);
        nb::gil_scoped_release release;
        socialnav::route_distances(walls.view(), pts, static_cast<int>(n), g, radius, o);
      },
      "points"_a, "goal"_a, "radius"_a, "obstacle_vertices"_a, "obstacle_offsets"_a, "out"_a.noconvert(),
      "Free-space distances [m] of a disc of radius from each of points (n, 2) to goal (2,) around the obstacles "
      "(the visibility graph inflated by the radius), written into out (n,); inf where the goal cannot be reached.");

  m.def(
      "lidar_scan",
      [](Array<double> eye, double heading, int beams, double fov, double range, Array<double> disc_positions,
         Array<double> disc_radii, Array<double> obstacle_vertices, Array<int64_t> obstacle_offsets) {
        if (beams < 1) throw std::invalid_argument("beams must be >= 1");
        if (!(fov > 0.0 && fov <= 2.0 * M_PI)) throw std::invalid_argument("fov must be in (0, 2 pi]");
        const size_t n = disc_radii.size();
        checked(eye, "eye", 2);
        checked(disc_positions, "disc_positions", 2 * n);
        const int P = polygon_count(obstacle_vertices, obstacle_offsets);
        const socialnav::PreparedObstacles walls =
            socialnav::prepare_obstacles(obstacle_vertices.data(), obstacle_offsets.data(), P);
        const std::vector<double> angles = socialnav::lidar_beam_angles(beams, fov);
        std::vector<double> c(angles.size()), s(angles.size()), out(angles.size());
        for (size_t i = 0; i < angles.size(); ++i) {
          c[i] = std::cos(angles[i]);
          s[i] = std::sin(angles[i]);
        }
        socialnav::lidar_scan(vec(eye), heading, c.data(), s.data(), beams, range, walls.view(), disc_positions.data(),
                              disc_radii.data(), nullptr, static_cast<int>(n), out.data(), fov);
        return out;
      },
      "eye"_a, "heading"_a, "beams"_a, "fov"_a, "range"_a, "disc_positions"_a, "disc_radii"_a, "obstacle_vertices"_a,
      "obstacle_offsets"_a,
      "One lidar scan from eye (the world's own, sensing.hpp): the distance along each beam (heading + "
      "lidar_beam_angles) to the nearest wall edge or disc, range where none.");
  m.def("lidar_beam_angles", &socialnav::lidar_beam_angles, "beams"_a, "fov"_a,
        "The beams' angles relative to the heading: over a full circle -pi + i 2pi/n; over a sector -fov/2 + i "
        "fov/(n-1).");
  m.def(
      "disc_in_sight",
      [](Array<double> eye, Array<double> centre, double radius, Array<double> other_positions,
         Array<double> other_radii, Array<double> obstacle_vertices, Array<int64_t> obstacle_offsets) {
        const size_t n = other_radii.size();
        checked(eye, "eye", 2);
        checked(centre, "centre", 2);
        checked(other_positions, "other_positions", 2 * n);
        const int P = polygon_count(obstacle_vertices, obstacle_offsets);
        const socialnav::PreparedObstacles walls =
            socialnav::prepare_obstacles(obstacle_vertices.data(), obstacle_offsets.data(), P);
        return socialnav::disc_in_sight(vec(eye), vec(centre), radius, walls.view(), other_positions.data(),
                                        other_radii.data(), nullptr, static_cast<int>(n));
      },
      "eye"_a, "centre"_a, "radius"_a, "other_positions"_a, "other_radii"_a, "obstacle_vertices"_a,
      "obstacle_offsets"_a,
      "Whether some point of the disc is in sight from eye past the walls and the other discs (the occlusion "
      "rule of the robot's detections).");
  m.def("route_cache_size", &socialnav::route_cache_size, "Maps whose route graphs the process holds now.");
  m.def("clear_route_cache", &socialnav::clear_route_cache, "Drops every cached route graph.");
}
