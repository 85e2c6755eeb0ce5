"""CrowdNav's published ORCA row (Chen et al., ICRA 2019) under its own setting.

Circle crossing, 5 decentralized ORCA humans, invisible ORCA robot with safety space 0, v_pref 1,
dt 0.25, 25 s limit, crowdsim_compat. CrowdNav reports success 0.43, collision 0.57 and a navigation
time of 10.9 s over 500 test episodes; the binomial standard error at n = 500 is 0.022.
"""

import numpy as np
import pytest

from socialnav.policies import make_policy
from socialnav.scenarios import make_scenario
from socialnav.sim.settings import WorldSettings
from socialnav.sim.world import World


def test_orca_row_of_crowdnav_is_reproduced():
    settings = WorldSettings(time_limit=25.0, crowdsim_compat=True, orca_mode="decentralized")
    world = World(settings, make_scenario("circle_crossing", n_humans=5, robot_v_pref=1.0), 250, split="test",
                  count=500)
    policy = make_policy("orca", safety_space=0.0)
    world.reset()
    trajs = []
    while world.busy:
        trajs += world.step(policy.act(world.observe())).finished
    outcome = np.array([t.outcome for t in trajs])
    success = float(np.mean(outcome == "success"))
    collision = float(np.mean(outcome == "collision"))
    nav_time = float(np.mean([(t.positions.shape[0] - 1) * t.dt for t in trajs if t.outcome == "success"]))
    print(f"success {success:.3f} collision {collision:.3f} nav time {nav_time:.2f} s")
    assert len(trajs) == 500
    assert success == pytest.approx(0.43, abs=0.05)
    assert collision == pytest.approx(0.57, abs=0.05)
    assert nav_time == pytest.approx(10.9, abs=0.5)
