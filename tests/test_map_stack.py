"""MapStack (one map per episode, vectorised) agrees with StaticMap.distance map by map."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from socialnav.maps.static_map import MapStack, StaticMap


def _square(cx: float, cy: float, half: float, turn: float) -> np.ndarray:
    c, s = np.cos(turn), np.sin(turn)
    corners = np.array([[-half, -half], [half, -half], [half, half], [-half, half]])
    return corners @ np.array([[c, s], [-s, c]]) + [cx, cy]


coord = st.floats(-5, 5, allow_nan=False)
shapes = st.one_of(
    st.builds(_square, coord, coord, st.floats(0.1, 2), st.floats(0, 1.6)),
    st.tuples(coord, coord, coord, coord).filter(lambda t: abs(t[0] - t[2]) + abs(t[1] - t[3]) > 1e-2)
    .map(lambda t: np.array(t).reshape(2, 2)),
    st.just(np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 3.0], [2.0, 1.0], [0.0, 3.0]])),  # non-convex
)
maps = st.lists(shapes, max_size=5).map(StaticMap.from_polygons)


@settings(max_examples=60, deadline=None)
@given(st.lists(maps, min_size=1, max_size=6), st.integers(0, 2**32 - 1))
def test_stack_matches_each_map(episode_maps: list[StaticMap], seed: int) -> None:
    points = np.random.default_rng(seed).uniform(-6, 6, size=(len(episode_maps), 7, 2))
    stacked = MapStack(episode_maps).distance(points)
    for i, smap in enumerate(episode_maps):
        np.testing.assert_allclose(stacked[i], smap.distance(points[i]), rtol=1e-12, atol=1e-12)
    rows = np.arange(len(episode_maps))[::-1]
    np.testing.assert_array_equal(MapStack(episode_maps).take(rows).distance(points[rows]), stacked[rows])


def test_hand_computed() -> None:
    box = StaticMap.from_polygons([[[0, 0], [2, 0], [2, 2], [0, 2]]])
    wall = StaticMap.from_polygons([[[0, 0], [0, 4]]])
    d = MapStack([box, wall, StaticMap()]).distance(np.array([[[1.0, 1.0], [3.0, 1.0]],
                                                              [[1.0, 1.0], [0.0, 5.0]],
                                                              [[1.0, 1.0], [0.0, 0.0]]]))
    np.testing.assert_allclose(d, [[0.0, 1.0], [1.0, 1.0], [np.inf, np.inf]])


def test_overlapping_solids_are_their_union() -> None:
    twice = StaticMap.from_polygons([[[0, 0], [2, 0], [2, 2], [0, 2]], [[1, 1], [3, 1], [3, 3], [1, 3]]])
    common = np.array([1.5, 1.5])  # inside both: still inside (an even-odd count over all edges would say no)
    assert twice.contains(common) and twice.distance(common) == 0.0
    assert MapStack([twice]).distance(common[None, None])[0, 0] == 0.0
