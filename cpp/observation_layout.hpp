// The layout of the policies' observation rows, shared by the world (World::observe), the native robot
// policies and the bindings. The same columns are socialnav.sim.observation's ROBOT_COLUMNS["world"] and
// HUMAN_COLUMNS["world"]; the core exports these widths (_core.ROBOT_FEATURES, _core.HUMAN_FEATURES) and
// tests/sim/test_observation_layout.py holds the two definitions equal.
#pragma once

namespace socialnav {

constexpr int kRobotFeatures = 9;  // px, py, vx, vy, radius, gx, gy, v_pref, theta
constexpr int kHumanFeatures = 5;  // px, py, vx, vy, radius

}  // namespace socialnav
