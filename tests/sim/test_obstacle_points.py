"""The obstacle point encoding (socialnav.sim.obstacle_points) against hand-built maps: where the
points are, which K are kept, the range, the padding, and a property test against a per-episode
brute force."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from socialnav.maps.static_map import StaticMap
from socialnav.settings import ConfigError
from socialnav.sim.obstacle_points import ObstaclePoints, append_obstacle_agents, outline_points

WALL = [[0.0, 0.0], [1.2, 0.0]]  # 1.2 m: cut into ceil(1.2 / 0.5) = 3 parts of 0.4 m
SQUARE = [[2.0, 2.0], [3.0, 2.0], [3.0, 3.0], [2.0, 3.0]]  # 1 m edges: 2 parts of 0.5 m each


def test_outline_points_by_hand():
    pts = outline_points(StaticMap((WALL, SQUARE)), 0.5)
    expected = [
        [0.0, 0.0], [0.4, 0.0], [0.8, 0.0], [1.2, 0.0],  # the wall: both ends
        [2.0, 2.0], [2.5, 2.0], [3.0, 2.0], [3.0, 2.5],  # the square: every vertex once
        [3.0, 3.0], [2.5, 3.0], [2.0, 3.0], [2.0, 2.5],
    ]
    np.testing.assert_allclose(pts, expected, atol=1e-12)
    assert not pts.flags.writeable


def test_an_edge_exactly_a_multiple_of_the_spacing_gets_no_extra_point():
    pts = outline_points(StaticMap(([[0.0, 0.0], [1.0, 0.0]],)), 0.5)
    np.testing.assert_allclose(pts, [[0.0, 0.0], [0.5, 0.0], [1.0, 0.0]])
    # a short edge still gives its ends
    np.testing.assert_allclose(outline_points(StaticMap(([[0.0, 0.0], [0.1, 0.0]],)), 0.5),
                               [[0.0, 0.0], [0.1, 0.0]])


def test_nearest_k_kept_nearest_first_then_padding():
    m = StaticMap((WALL, SQUARE))
    enc = ObstaclePoints(count=3, spacing=0.5, range=4.0)
    points, mask = enc.nearest(np.array([[0.5, 1.0]]), [m])
    # distances from (0.5, 1): (0.4, 0) 1.005, (0.8, 0) 1.044, (0, 0) 1.118, (1.2, 0) 1.221 ...
    np.testing.assert_allclose(points[0], [[0.4, 0.0], [0.8, 0.0], [0.0, 0.0]])
    assert mask.tolist() == [[True, True, True]]


def test_range_leaves_far_points_out_and_pads_with_zeros():
    m = StaticMap((WALL, SQUARE))
    enc = ObstaclePoints(count=6, spacing=0.5, range=1.1)
    points, mask = enc.nearest(np.array([[0.5, 1.0]]), [m])
    # within 1.1 m of (0.5, 1): only (0.4, 0) and (0.8, 0)
    assert mask.tolist() == [[True, True, False, False, False, False]]
    np.testing.assert_allclose(points[0, :2], [[0.4, 0.0], [0.8, 0.0]])
    assert np.all(points[0, 2:] == 0.0)


def test_open_floor_rows_are_all_padding_and_rows_keep_their_own_maps():
    a, b = StaticMap((WALL,)), StaticMap((SQUARE,))
    enc = ObstaclePoints(count=2)
    pos = np.array([[0.0, -0.3], [0.0, 0.0], [2.5, 2.5], [1.2, 0.3]])
    points, mask = enc.nearest(pos, [a, None, b, a])
    assert mask.tolist() == [[True, True], [False, False], [True, True], [True, True]]
    np.testing.assert_allclose(points[0], [[0.0, 0.0], [0.4, 0.0]])
    assert np.all(points[1] == 0.0)
    np.testing.assert_allclose(points[2], [[2.5, 2.0], [3.0, 2.5]])  # 4 points at 0.5 m: outline order
    np.testing.assert_allclose(points[3], [[1.2, 0.0], [0.8, 0.0]])


def test_agents_are_standing_discs_appended_after_the_humans():
    enc = ObstaclePoints(count=2, radius=0.1)
    robot = np.zeros((1, 9))
    robot[0, :2] = [0.6, 0.5]
    humans = np.array([[[5.0, 5.0, 1.0, 0.0, 0.3]]])
    h, m = append_obstacle_agents(robot, humans, np.array([[True]]), [StaticMap((WALL,))], enc)
    assert h.shape == (1, 3, 5) and m.tolist() == [[True, True, True]]
    np.testing.assert_array_equal(h[0, 0], humans[0, 0])
    np.testing.assert_allclose(h[0, 1:], [[0.4, 0.0, 0.0, 0.0, 0.1], [0.8, 0.0, 0.0, 0.0, 0.1]])
    h, m = append_obstacle_agents(robot, humans, np.array([[True]]), None, enc)
    assert m.tolist() == [[True, False, False]] and np.all(h[0, 1:] == 0.0)


def test_bad_encodings_are_named():
    with pytest.raises(ConfigError, match="obstacle_encoding.count"):
        ObstaclePoints(count=0)
    with pytest.raises(ConfigError, match="obstacle_encoding.spacing"):
        ObstaclePoints(spacing=float("nan"))
    with pytest.raises(ConfigError, match="obstacle_encoding.kind"):
        ObstaclePoints.from_dict({"kind": "segments"})
    with pytest.raises(ConfigError, match="sapcing"):
        ObstaclePoints.from_dict({"sapcing": 0.5})
    enc = ObstaclePoints(count=8, spacing=0.25, range=3.0, radius=0.05)
    assert ObstaclePoints.from_dict(enc.to_dict()) == enc


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.tuples(st.floats(-5, 5), st.floats(-5, 5), st.floats(-5, 5), st.floats(-5, 5)),
             min_size=1, max_size=5),
    st.lists(st.tuples(st.floats(-6, 6), st.floats(-6, 6)), min_size=1, max_size=6),
    st.integers(1, 12),
    st.floats(0.1, 2.0),
    st.floats(0.5, 8.0),
)
def test_nearest_equals_a_brute_force_per_episode(walls, positions, count, spacing, rng):
    segs = [[[x1, y1], [x2, y2]] for x1, y1, x2, y2 in walls if np.hypot(x2 - x1, y2 - y1) > 1e-3]
    if not segs:
        return
    m = StaticMap(tuple(segs))
    enc = ObstaclePoints(count=count, spacing=spacing, range=rng)
    pos = np.array(positions)
    points, mask = enc.nearest(pos, [m] * len(pos))
    outline = outline_points(m, spacing)
    for seg in segs:  # each wall: from end to end, neighbours at most `spacing` apart and evenly spaced
        own = outline_points(StaticMap((seg,)), spacing)
        np.testing.assert_allclose(own[[0, -1]], seg, atol=1e-12)
        gaps = np.hypot(*np.diff(own, axis=0).T)
        assert np.all(gaps <= spacing + 1e-9) and np.allclose(gaps, gaps[0])
    for b, p in enumerate(pos):
        d = np.hypot(*(outline - p).T)
        within = np.flatnonzero(d <= rng)
        kept = within[np.argsort(d[within], kind="stable")][:count]
        assert mask[b].sum() == len(kept)
        np.testing.assert_array_equal(points[b, : len(kept)], outline[kept])
        assert np.all(points[b, len(kept):] == 0.0)
        assert np.all(np.diff(np.hypot(*(points[b, : len(kept)] - p).T)) >= 0)  # nearest first
