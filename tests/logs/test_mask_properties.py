"""Property: an agent absent from the data changes no metric; one present at a few samples only
counts there (compared with a scene in which it is far away elsewhere)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from socialnav.metrics import score_episode
from socialnav.trajectory import Trajectory
from tests.metrics.test_properties import scenes


def _same(a: dict, b: dict, skip: tuple[str, ...] = ()) -> None:
    for k in a:
        if not k.startswith(skip):
            assert a[k] == pytest.approx(b[k], rel=1e-9, abs=1e-9, nan_ok=True), k


@given(scenes(min_humans=0, max_humans=3), st.floats(-5, 5), st.floats(-5, 5))
@settings(max_examples=60, deadline=None)
def test_absent_agent_changes_nothing(traj: Trajectory, gx: float, gy: float) -> None:
    k1 = traj.n_steps + 1
    ghost = np.full((k1, 1, 2), [gx, gy]) + np.linspace(0, 1, k1)[:, None, None]
    pos = np.concatenate([traj.positions, ghost], axis=1)
    present = np.ones(pos.shape[:2], bool)
    present[:, -1] = False
    more = Trajectory.from_positions(pos, traj.dt, radii=np.append(traj.radii, 0.3),
                                     v_pref=np.append(traj.v_pref, 1.0), goals=pos[-1], present=present,
                                     outcome=traj.outcome)
    # M_VI is defined per number of humans in the trajectory, which the ghost changes
    _same(score_episode(traj), score_episode(more), skip=("m6_",))


@given(scenes(min_humans=1, max_humans=3), st.data())
@settings(max_examples=60, deadline=None)
def test_masked_samples_equal_a_far_away_agent_for_distance_metrics(traj: Trajectory, data) -> None:
    # hiding human 1 at some samples = moving it 1 km away there, for the distance-based metrics
    k1 = traj.n_steps + 1
    mask = np.array(data.draw(st.lists(st.booleans(), min_size=k1, max_size=k1)))
    present = np.ones((k1, traj.n_agents), bool)
    present[:, 1] = mask
    masked = Trajectory.from_positions(traj.positions, traj.dt, radii=traj.radii, v_pref=traj.v_pref,
                                       goals=traj.goals, present=present, outcome=traj.outcome)
    far = np.array(traj.positions)
    far[~mask, 1] = [1000.0, 1000.0]
    moved = Trajectory.from_positions(far, traj.dt, radii=traj.radii, v_pref=traj.v_pref, goals=traj.goals,
                                      outcome=traj.outcome)
    a, b = score_episode(masked), score_episode(moved)
    nobody = not present[1:, 1:].any()  # no human present at samples 1..K: no clearance at all
    assert np.isnan(a["min_clearance"]) == nobody
    if not nobody:
        assert a["min_clearance"] == pytest.approx(b["min_clearance"])
    for key in ("discomfort.count@threshold=0.2",
                "m1_personal_space.count@eps=0.2,distance=clearance",
                "m1_personal_space.count@eps=1.2,distance=clearance"):
        assert a[key] == pytest.approx(b[key], nan_ok=True), key
