// Social-force pedestrians: Helbing & Molnár's model with their wall repulsion.
//
// D. Helbing, P. Molnár, "Social force model for pedestrian dynamics", Physical Review E 51(5),
// 4282-4286, 1995 (the algorithm: cpp/social_force.cpp). Preferred (desired) velocity: v_pref towards
// the target, easing off inside its last metre; the speed is capped at max_speed_factor * v_pref (Eq. 6).
#include <cmath>
#include <vector>

#include "behaviour.hpp"
#include "builtin_params.hpp"
#include "social_force.hpp"

namespace socialnav {

SocialForceParams social_force_values(const ParamValues& v) {
  SocialForceParams p;
  p.relaxation_time = v.get("relaxation_time");
  p.v0 = v.get("v0");
  p.sigma = v.get("sigma");
  p.step_time = v.get("step_time");
  p.fov_half_angle = v.get("fov_half_angle") * (M_PI / 180.0);  // as numpy.deg2rad, bit for bit
  p.outside_fov_weight = v.get("outside_fov_weight");
  p.max_speed_factor = v.get("max_speed_factor");
  p.wall_u0 = v.get("wall_u0");
  p.wall_r = v.get("wall_r");
  return p;
}

namespace {

class SocialForceBehaviour final : public HumanBehaviour {
 public:
  explicit SocialForceBehaviour(const BehaviourSetup& setup)
      : params_(social_force_values(setup.params)),
        others_(setup.threads, std::vector<SocialForceOther>(setup.agents)) {}

  Vec2 preferred_velocity(Vec2 position, Vec2 target, double v_pref, double) const override {
    return social_force_desired_velocity(position, target, v_pref);
  }

  void preferred_velocities(const SlotView& s, const double* targets, Vec2* out) const override {
    fill_preferred_velocities(*this, s, targets, out);
  }

  void velocities(const SlotView& s, int worker, double* out) override {
    std::vector<SocialForceOther>& others = others_[worker];
    for (int i = 1; i < s.agents; ++i) {
      if (!s.mask[i]) continue;
      int n = 0;
      for (int j = s.first_other(); j < s.agents; ++j) {
        if (j == i || !s.mask[j]) continue;
        others[n++] = SocialForceOther{s.at(s.position, j), s.at(s.velocity, j)};
      }
      const SocialForceAgent self{s.at(s.position, i), s.at(s.velocity, i), s.preferred[i],
                                  params_.max_speed_factor * s.v_pref[i]};
      const Vec2 v = social_force_new_velocity(self, others.data(), n, params_, s.dt, s.obstacles);
      out[2 * i] = v.x;
      out[2 * i + 1] = v.y;
    }
  }

 private:
  SocialForceParams params_;
  std::vector<std::vector<SocialForceOther>> others_;  // one per worker thread, A entries
};

std::unique_ptr<HumanBehaviour> make(const BehaviourSetup& setup) {
  return std::make_unique<SocialForceBehaviour>(setup);
}

std::vector<BehaviourParam> params() {
  return {
      BehaviourParam("relaxation_time", 0.5, "s", "tau: relaxation time towards the desired velocity").above(0),
      BehaviourParam("v0", 2.1, "m^2/s^2", "V0: repulsion strength").at_least(0),
      BehaviourParam("sigma", 0.3, "m", "repulsion range").above(0),
      BehaviourParam("step_time", 2.0, "s", "delta t for the other's step").above(0),
      BehaviourParam("fov_half_angle", 100.0, "deg", "phi: half angle of the field of view"),
      BehaviourParam("outside_fov_weight", 0.5, "", "c: weight of forces from outside the field of view")
          .at_least(0)
          .at_most(1),
      BehaviourParam("max_speed_factor", 1.3, "", "v_max / v_desired").above(0),
      BehaviourParam("wall_u0", 10.0, "m^2/s^2", "U0: wall repulsion strength (Helbing & Molnár 1995)").at_least(0),
      BehaviourParam("wall_r", 0.2, "m", "R: wall repulsion range (Helbing & Molnár 1995)").above(0),
  };
}

const BehaviourRegistrar registrar(BehaviourInfo{
    "social_force",
    "social force model (Helbing & Molnár 1995) with wall repulsion: v_pref towards the goal, easing off in "
    "the last metre",
    1, params(), make});

}  // namespace

}  // namespace socialnav
