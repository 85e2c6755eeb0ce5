// ORCA pedestrians as CrowdSim simulates them: RVO2's reciprocal collision avoidance among the
// other agents and the slot's static obstacles.
//
// J. van den Berg, S. J. Guy, M. Lin, D. Manocha, "Reciprocal n-body collision avoidance", Robotics
// Research (ISRR 2009), Springer Tracts in Advanced Robotics 70, 2011, pp. 3-19 (the algorithm:
// cpp/orca.cpp). Preferred velocity: CrowdSim's, the vector to the target cut to 1 m/s beyond 1 m
// (C. Chen et al., "Crowd-robot interaction", ICRA 2019); the new speed is at most v_pref.
#include <vector>

#include "behaviour.hpp"
#include "builtin_params.hpp"
#include "orca.hpp"

namespace socialnav {

OrcaValues orca_values(const ParamValues& v) {
  OrcaValues out{};
  out.solver.neighbor_dist = v.get("neighbor_dist");
  out.solver.max_neighbors = v.get_int("max_neighbors");
  out.solver.time_horizon = v.get("time_horizon");
  out.solver.time_horizon_obst = v.get("time_horizon_obst");
  out.radius_margin = v.get("radius_margin");
  out.safety_space = v.get("safety_space");
  return out;
}

namespace {

class OrcaBehaviour final : public HumanBehaviour {
 public:
  explicit OrcaBehaviour(const BehaviourSetup& setup)
      : values_(orca_values(setup.params)),
        scratch_(setup.threads),
        neighbors_(setup.threads, std::vector<OrcaNeighbor>(setup.agents)) {}

  Vec2 preferred_velocity(Vec2 position, Vec2 target, double, double) const override {
    return crowdsim_pref_velocity(position, target);
  }

  void preferred_velocities(const SlotView& s, const double* targets, Vec2* out) const override {
    fill_preferred_velocities(*this, s, targets, out);
  }

  void velocities(const SlotView& s, int worker, double* out) override {
    const OrcaParams& params = values_.solver;
    OrcaScratch& scratch = scratch_[worker];
    std::vector<OrcaNeighbor>& nb = neighbors_[worker];
    const double margin = values_.radius_margin + values_.safety_space;
    for (int i = 1; i < s.agents; ++i) {
      if (!s.mask[i]) continue;
      const Vec2 p = s.at(s.position, i);
      scratch.begin(params.neighbor_dist);
      for (int j = s.first_other(); j < s.agents; ++j) {
        if (j == i || !s.mask[j]) continue;
        scratch.offer(j, abs_sq(s.at(s.position, j) - p), params.max_neighbors);
      }
      for (int k = 0; k < scratch.count; ++k) {
        const int j = scratch.index[k];
        nb[k] = OrcaNeighbor{s.at(s.position, j), s.at(s.velocity, j), s.radius[j] + margin};
      }
      const OrcaAgent self{p, s.at(s.velocity, i), s.radius[i] + margin, s.v_pref[i], s.preferred[i]};
      const Vec2 v = orca_new_velocity(self, s.orca_obstacles, params.time_horizon_obst, nb.data(), scratch.count,
                                       params.time_horizon, s.dt, scratch);
      out[2 * i] = v.x;
      out[2 * i + 1] = v.y;
    }
  }

 private:
  OrcaValues values_;
  std::vector<OrcaScratch> scratch_;                  // one per worker thread
  std::vector<std::vector<OrcaNeighbor>> neighbors_;  // one per worker thread, A entries
};

std::unique_ptr<HumanBehaviour> make(const BehaviourSetup& setup) { return std::make_unique<OrcaBehaviour>(setup); }

std::vector<BehaviourParam> params() {
  return {
      BehaviourParam("neighbor_dist", 10.0, "m", "agents farther than this are ignored").above(0),
      BehaviourParam("max_neighbors", 10, "", "nearest agents considered")
          .whole()
          .at_least(0)
          .at_most(kMaxOrcaNeighbors),
      BehaviourParam("time_horizon", 5.0, "s", "time horizon of the velocity obstacles of agents").above(0),
      BehaviourParam("time_horizon_obst", 5.0, "s", "time horizon for static obstacles (CrowdSim's timeHorizonObst)")
          .above(0),
      BehaviourParam("radius_margin", 0.01, "m", "CrowdSim inflates every radius by 1 cm").at_least(0),
      BehaviourParam("safety_space", 0.0, "m", "extra inflation used by the humans").at_least(0),
  };
}

const BehaviourRegistrar registrar(BehaviourInfo{
    "orca",
    "ORCA (van den Berg et al. 2011) with RVO2's obstacle lines, as CrowdSim's humans: towards the goal at "
    "up to 1 m/s, never faster than v_pref",
    0, params(), make});

}  // namespace

}  // namespace socialnav
