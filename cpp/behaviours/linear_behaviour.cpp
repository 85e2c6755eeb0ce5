// Linear pedestrians: straight to the target at v_pref, ignoring everyone and every wall (the
// non-reactive humans of CrowdNav's test settings; C. Chen et al., "Crowd-robot interaction", ICRA 2019).
#include <vector>

#include "behaviour.hpp"

namespace socialnav {

namespace {

class LinearBehaviour final : public HumanBehaviour {
 public:
  Vec2 preferred_velocity(Vec2 position, Vec2 target, double v_pref, double dt) const override {
    return straight_to_goal_velocity(position, target, v_pref, dt);
  }

  void preferred_velocities(const SlotView& s, const double* targets, Vec2* out) const override {
    fill_preferred_velocities(*this, s, targets, out);
  }

  void velocities(const SlotView& s, int, double* out) override {
    for (int i = 1; i < s.agents; ++i) {
      if (!s.mask[i]) continue;
      out[2 * i] = s.preferred[i].x;
      out[2 * i + 1] = s.preferred[i].y;
    }
  }
};

std::unique_ptr<HumanBehaviour> make(const BehaviourSetup&) { return std::make_unique<LinearBehaviour>(); }

const BehaviourRegistrar registrar(BehaviourInfo{
    "linear", "straight to the goal at v_pref, never passing it, ignoring the others and the walls", 2, {}, make});

}  // namespace

}  // namespace socialnav
