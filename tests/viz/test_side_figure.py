"""The report's M_VI figure: its four groups per scenario and policy, the one-human encounters included."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from socialnav.viz.figures import side_bars  # noqa: E402  (after the skip)


def _heights(fig) -> dict[str, list[float]]:
    ax = fig.axes[0]
    return {c.get_label(): [b.get_height() for b in c.patches] for c in ax.containers}


def test_every_case_is_in_one_of_the_four_groups_and_encounters_count():
    sweep = [{"policy": "p", "scenario": "passing", "visibility": "invisible", "side": s}
             for s in ("left", "left", "right", "never_level", "failed")]
    # frontal_approach rows carry no side: it is read from their M_VI values (invisible pass only)
    m6 = {"m6_side_preference.sign@frame=world": 1.0, "m6_side_preference.level@frame=world": 1.0}
    base = {"policy": "p", "scenario": "frontal_approach", "n_humans": 1.0, **m6}
    encounter = [{**base, "visibility": "invisible", "outcome": "success", "success": 1.0},
                 {**base, "visibility": "invisible", "outcome": "timeout", "success": 0.0},
                 {**base, "visibility": "visible", "outcome": "success", "success": 1.0}]
    fig = side_bars(sweep + encounter)
    heights = _heights(fig)
    # groups: (passing, p), (frontal_approach, p)
    assert heights["left"] == [40.0, 50.0] and heights["right"] == [20.0, 0.0]
    assert heights["unlabelled"] == [20.0, 0.0] and heights["failed"] == [20.0, 50.0]
    assert np.allclose(np.sum(list(heights.values()), axis=0), 100.0)  # every case drawn once
    assert side_bars([{"policy": "p", "scenario": "intersection", "visibility": "invisible"}]) is None
