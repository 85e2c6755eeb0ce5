"""The observation rows have one layout: the core's widths (cpp/observation_layout.hpp, exported as
_core.ROBOT_FEATURES and _core.HUMAN_FEATURES) are the columns socialnav.sim.observation declares, which
every observation part, learner observation, env and network reads."""

import numpy as np
import pytest

from socialnav import _core
from socialnav.sim.observation import HUMAN_COLUMNS, HUMAN_DIM, ROBOT_COLUMNS, ROBOT_DIM


def test_the_cores_widths_are_the_declared_columns():
    assert _core.ROBOT_FEATURES == ROBOT_DIM == len(ROBOT_COLUMNS["world"])
    assert _core.HUMAN_FEATURES == HUMAN_DIM == len(HUMAN_COLUMNS["world"])


def test_the_cores_robot_policies_refuse_another_width_naming_it():
    """The native policies check the rows against the same constants (the message names the width)."""
    from socialnav.policies import make_policy
    from socialnav.sim.observation import Observation

    B, N = 2, 3
    wrong = Observation(np.zeros((B, ROBOT_DIM + 1)), np.zeros((B, N, HUMAN_DIM)), np.zeros((B, N), bool),
                        np.ones(B, bool), np.zeros(B), 0.25, "holonomic")
    with pytest.raises(ValueError, match=rf"\(B, {ROBOT_DIM}\)"):
        make_policy("orca", threads=1).act(wrong)
