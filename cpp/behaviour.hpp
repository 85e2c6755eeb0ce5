// Pedestrian behaviours as registered components: how the humans of one episode slot choose their
// next velocities (docs/extending.md, "A pedestrian behaviour"; docs/simulator.md, "Human models").
//
// A behaviour answers two questions, kept apart so that either can be replaced on its own:
//  1. Where does a human want to go? `preferred_velocity`: the behaviour's own law for heading to a
//     target point at its preferred speed. The world passes each human's goal, or with human_routes
//     among walls the point of the human's route it heads for (routes.hpp, RouteFollower::target).
//  2. How does it avoid the others? `velocities`: the new velocities of the slot's humans from their
//     preferred velocities, the other agents (the robot only where it is visible) and the slot's
//     static obstacles.
// Each behaviour is a class in a file of its own under cpp/behaviours/ that declares its parameters
// once (BehaviourParam: name, default, unit, description, bounds) and registers itself by name with a
// static BehaviourRegistrar. The world dispatches through the registry; the bindings list it
// (_core.human_behaviours()), and the Python settings, `socialnav list` and the docs read the same
// declarations. CMake compiles every cpp/behaviours/*.cpp, so a new behaviour is one file and its test.
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "obstacles.hpp"
#include "vec2.hpp"

namespace socialnav {

// One declared parameter. Values travel as doubles (an integer parameter holds a whole number).
// Bounds are open (above, below) or closed (at_least, at_most); NaN: no bound.
struct BehaviourParam {
  std::string name;
  double default_value = 0.0;
  std::string unit;         // SI unit, "" when dimensionless
  std::string description;  // one line
  bool integer = false;
  double gt = std::numeric_limits<double>::quiet_NaN();
  double ge = std::numeric_limits<double>::quiet_NaN();
  double lt = std::numeric_limits<double>::quiet_NaN();
  double le = std::numeric_limits<double>::quiet_NaN();

  BehaviourParam(std::string name_, double default_, std::string unit_, std::string description_)
      : name(std::move(name_)), default_value(default_), unit(std::move(unit_)), description(std::move(description_)) {}
  BehaviourParam& whole() {
    integer = true;
    return *this;
  }
  BehaviourParam& above(double x) {
    gt = x;
    return *this;
  }
  BehaviourParam& at_least(double x) {
    ge = x;
    return *this;
  }
  BehaviourParam& below(double x) {
    lt = x;
    return *this;
  }
  BehaviourParam& at_most(double x) {
    le = x;
    return *this;
  }
};

// The values of one behaviour's parameters, in declared order, checked against the declaration.
class ParamValues {
 public:
  // `values` empty: every default. Throws std::invalid_argument naming `behaviour` and the parameter
  // for a wrong count, a non-finite value, a fraction for an integer parameter or a value out of bounds.
  // `params` must outlive the values (a registered behaviour's declaration does).
  ParamValues(const std::string& behaviour, const std::vector<BehaviourParam>& params,
              const std::vector<double>& values);
  // The value of parameter `name` (a name the behaviour does not declare throws std::logic_error).
  double get(const std::string& name) const;
  int get_int(const std::string& name) const { return static_cast<int>(get(name)); }
  const std::vector<double>& values() const { return values_; }

 private:
  const std::vector<BehaviourParam>* params_;
  std::string behaviour_;
  std::vector<double> values_;
};

// One episode slot as a behaviour sees it (agent 0 is the robot; arrays of A = 1 + N agents).
struct SlotView {
  int agents = 0;
  const double* position = nullptr;  // (A, 2) [m]
  const double* velocity = nullptr;  // (A, 2) velocity applied in the last step [m/s]
  const double* goal = nullptr;      // (A, 2) goal each agent had at reset [m]
  const double* radius = nullptr;    // (A,) [m]
  const double* v_pref = nullptr;    // (A,) preferred speed [m/s]
  const uint8_t* mask = nullptr;     // (A,) real agents
  const Vec2* preferred = nullptr;   // (A,) the humans' preferred velocities [m/s] (entry 0 unused)
  bool robot_visible = false;        // the humans react to agent 0
  ObstacleView obstacles;            // the slot's static map (count 0: open floor)
  ObstacleView orca_obstacles;       // the same map as RVO2's ORCA sees it (OrcaObstacles)
  double dt = 0.25;                  // [s]
  int first_other() const { return robot_visible ? 0 : 1; }
  Vec2 at(const double* xy, int i) const { return Vec2{xy[2 * i], xy[2 * i + 1]}; }
};

class HumanBehaviour {
 public:
  virtual ~HumanBehaviour() = default;
  // Question 1: the velocity [m/s] with which a human at `position` heads for `target` (its goal, or
  // a route's waypoint), given its preferred speed v_pref [m/s] and the step dt [s].
  virtual Vec2 preferred_velocity(Vec2 position, Vec2 target, double v_pref, double dt) const = 0;
  // Question 1 for every real human i in [1, A) of a slot: out[i] = preferred_velocity(position i,
  // target i, v_pref i, dt), targets (A, 2) [m] (the goals, or a route's waypoints). This default calls
  // preferred_velocity through the vtable once per human; a behaviour overrides it with
  // fill_preferred_velocities(*this, ...), which calls its own law directly so that it is inlined.
  virtual void preferred_velocities(const SlotView& slot, const double* targets, Vec2* out) const;
  // Question 2: writes the new velocity of every real human i in [1, A) (mask[i]) to out[2i], out[2i+1]
  // [m/s]; other entries are left alone. `worker` in [0, threads) indexes per-thread scratch space:
  // calls with different workers run at the same time.
  virtual void velocities(const SlotView& slot, int worker, double* out) = 0;
};

// preferred_velocities' loop with behaviour B's own law, called without the vtable (B final), so that the
// compiler inlines it: one indirect call per slot instead of one per human.
template <class B>
void fill_preferred_velocities(const B& behaviour, const SlotView& s, const double* targets, Vec2* out) {
  for (int i = 1; i < s.agents; ++i)
    if (s.mask[i]) out[i] = behaviour.B::preferred_velocity(s.at(s.position, i), s.at(targets, i), s.v_pref[i], s.dt);
}

// What a behaviour is built from: its checked parameters, the world's worker threads and agents per slot.
struct BehaviourSetup {
  const ParamValues& params;
  int threads;
  int agents;
};

struct BehaviourInfo {
  std::string name;         // the key of WorldSettings.human_model
  std::string description;  // one line, citing the model's paper
  int order = 100;          // listing position (the built-ins come first), then by name
  std::vector<BehaviourParam> params;
  std::unique_ptr<HumanBehaviour> (*make)(const BehaviourSetup& setup) = nullptr;
};

// Every registered behaviour in listing order. Throws std::logic_error if two registered one name.
std::vector<const BehaviourInfo*> human_behaviours();
// The behaviour registered as `name`; throws std::invalid_argument naming the registered ones.
const BehaviourInfo& human_behaviour(const std::string& name);
// Builds behaviour `name` with parameter values in declared order (empty: the defaults).
std::unique_ptr<HumanBehaviour> make_human_behaviour(const std::string& name, const std::vector<double>& values,
                                                     int threads, int agents);

// Registers a behaviour when its file's statics are initialised:
//   static const BehaviourRegistrar registrar(BehaviourInfo{...});
struct BehaviourRegistrar {
  explicit BehaviourRegistrar(BehaviourInfo info);
};

}  // namespace socialnav
