"""Obstacle metrics against hand-computed values (metrics/obstacles.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from socialnav.evaluate.report import table2
from socialnav.evaluate.summary import summarize_group
from socialnav.maps.static_map import StaticMap
from socialnav.metrics import metric_key, score_episode
from socialnav.metrics.obstacles import min_obstacle_clearance, obstacle_proximity, wall_collision
from socialnav.trajectory import Trajectory

WALL = StaticMap.from_polygons([[[-5.0, 1.0], [5.0, 1.0]]])  # a wall segment along y = 1


def _robot_along_y(ys: list[float], smap: StaticMap | None, outcome: str = "success", **settings: object
                   ) -> Trajectory:
    """The robot (r = 0.3) at x = 0, the given y per sample, and one human far away; dt = 0.25 s."""
    pos = np.zeros((len(ys), 2, 2))
    pos[:, 0, 1] = ys
    pos[:, 1] = [20.0, 20.0]
    return Trajectory.from_positions(pos, 0.25, radii=0.3, v_pref=1.0, goals=np.zeros((2, 2)),
                                     outcome=outcome, static_map=smap, settings=settings)


def test_clearance_to_a_wall_segment_by_hand() -> None:
    # samples 1..4 at y = 0.3, 0.45, 0.6, 0.8: distances to y = 1 of 0.7, 0.55, 0.4, 0.2 m,
    # clearances (minus r = 0.3) 0.4, 0.25, 0.1, -0.1 m; sample 0 (y = 0) is the initial state, not scored
    tr = _robot_along_y([0.0, 0.3, 0.45, 0.6, 0.8], WALL)
    assert min_obstacle_clearance(tr)["value"] == pytest.approx(-0.1)
    assert obstacle_proximity(tr) == pytest.approx({"count": 2.0, "fraction": 0.5, "duration_s": 0.5})
    assert obstacle_proximity(tr, threshold=0.3) == pytest.approx({"count": 3.0, "fraction": 0.75,
                                                                   "duration_s": 0.75})


def test_clearance_to_a_solid_box_and_inside_it() -> None:
    box = StaticMap.from_polygons([[[2, -1], [3, -1], [3, 1], [2, 1]]])
    pos = np.zeros((3, 1, 2))
    pos[:, 0] = [[0.0, 0.0], [1.5, 0.0], [2.5, 0.0]]  # 0.5 m from the box's left face, then inside
    tr = Trajectory.from_positions(pos, 0.1, radii=0.3, goals=np.zeros((1, 2)), outcome="collision",
                                   static_map=box)
    assert min_obstacle_clearance(tr)["value"] == pytest.approx(-0.3)  # centre inside: distance 0
    first = Trajectory.from_positions(pos[:2], 0.1, radii=0.3, goals=np.zeros((1, 2)), static_map=box)
    assert min_obstacle_clearance(first)["value"] == pytest.approx(0.2)


def test_undefined_without_a_map() -> None:
    tr = _robot_along_y([0.0, 0.3, 0.6], None)
    assert math.isnan(min_obstacle_clearance(tr)["value"])
    assert all(math.isnan(v) for v in obstacle_proximity(tr).values())
    assert math.isnan(wall_collision(tr)["value"])


@pytest.mark.parametrize("outcome, settings, smap, expected", [
    ("collision", {"collision_kind": "obstacle"}, WALL, 1.0),
    ("collision", {"collision_kind": "human"}, WALL, 0.0),
    ("collision", {"collision_kind": "obstacle"}, None, 1.0),  # the simulator's word suffices
    ("success", {}, WALL, 0.0),
    ("timeout", {"collision_kind": "obstacle"}, WALL, 0.0),  # only collision episodes count
    ("unknown", {"collision_kind": "obstacle"}, WALL, math.nan),
    ("success", {}, None, math.nan),  # open floor: no wall rate at all
])
def test_wall_collision_indicator(outcome: str, settings: dict, smap: StaticMap | None,
                                  expected: float) -> None:
    tr = _robot_along_y([0.0, 0.3, 0.45], smap, outcome, **settings)
    value = wall_collision(tr)["value"]
    assert (math.isnan(value) and math.isnan(expected)) or value == expected


def test_wall_collision_without_kind_uses_the_clearance() -> None:
    touching = _robot_along_y([0.0, 0.3, 0.8], WALL, "collision")  # clearance -0.1 at the end
    clear = _robot_along_y([0.0, 0.3, 0.45], WALL, "collision")  # a collision with someone else
    assert wall_collision(touching)["value"] == 1.0 and wall_collision(clear)["value"] == 0.0
    with pytest.raises(ValueError, match="collision_kind.*'wall'"):
        wall_collision(_robot_along_y([0.0, 0.3], WALL, "collision", collision_kind="wall"))


@pytest.mark.parametrize(("human_y", "expected"), [
    (1.2, 0.0),  # the person overlaps the robot at the wall's sample (y = 0.8): a person, as the simulator
    (0.5, 0.0),  # the person was hit first, at y = 0.3 (centres 0.2 m apart)
    (5.0, 1.0),  # nobody near: the wall
])
def test_a_log_that_hit_a_person_and_a_wall_counts_what_came_first(human_y: float, expected: float) -> None:
    tr = _robot_along_y([0.0, 0.3, 0.8], WALL, "collision")
    pos = tr.positions.copy()
    pos[:, 1] = [0.0, human_y]  # a person standing on the robot's line
    tr = Trajectory.from_positions(pos, 0.25, radii=0.3, v_pref=1.0, goals=np.zeros((2, 2)),
                                   outcome="collision", static_map=WALL)
    assert wall_collision(tr)["value"] == expected


def test_score_episode_keys_and_wang_metrics_unchanged_by_a_map() -> None:
    ys = [0.0, 0.2, 0.45, 0.6]
    with_map, without = score_episode(_robot_along_y(ys, WALL)), score_episode(_robot_along_y(ys, None))
    # the map adds only the keys of the map_only metrics (progress among walls: test_progress.py)
    assert [k for k in with_map if k in without] == list(without)
    assert {k.split(".")[0] for k in with_map.keys() - without.keys()} == {
        "human_arrival", "humans_stuck", "robot_stuck_time"}
    assert with_map[metric_key("obstacle_proximity", "duration_s")] == pytest.approx(0.25)
    assert with_map[metric_key("min_obstacle_clearance")] == pytest.approx(0.1)
    for k, v in without.items():
        if not k.startswith(("min_obstacle_clearance", "obstacle_proximity", "wall_collision")):
            assert with_map[k] == v or (math.isnan(v) and math.isnan(with_map[k])), k
    assert "obstacle_proximity.duration_s@threshold=0.2" in with_map


def _rows(outcomes_kinds: list[tuple[str, str | None]], smap: StaticMap | None) -> list[dict]:
    rows = []
    for i, (outcome, kind) in enumerate(outcomes_kinds):
        settings = {} if kind is None else {"collision_kind": kind}
        tr = _robot_along_y([0.0, 0.3, 0.45], smap, outcome, **settings)
        rows.append({"policy": "orca", "scenario": "narrow_hallway", "visibility": "invisible", "index": i,
                     "outcome": outcome, **score_episode(tr)})
    return rows


def test_tables_report_wall_collisions_apart() -> None:
    runs = [("success", None), ("collision", "obstacle"), ("collision", "human"), ("success", None)]
    summary = [summarize_group(("orca", "narrow_hallway", "invisible"), _rows(runs, WALL))]
    assert summary[0]["collision_rate"] == 0.5 and summary[0]["wall_collision_rate"] == 0.25
    text = table2(summary)
    header = next(line for line in text.splitlines() if line.startswith("| Policy"))
    assert "| Collision % | Wall collision % | Timeout % |" in header
    assert "| orca | 50.00 | 50.00 | 25.00 | 0.00 |" in text
    assert "Note: Wall collision %: the episodes that ended in a collision with a wall" in text
    assert "as a share of all episodes; Collision % counts them too" in text
    # open floors: no column, as in the original protocol's tables
    open_summary = [summarize_group(("orca", "circle_crossing", "invisible"), _rows(runs[:1] * 2, None))]
    assert math.isnan(open_summary[0]["wall_collision_rate"])
    assert "Wall collision" not in table2(open_summary)  # neither the column nor its note
