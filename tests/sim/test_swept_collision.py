"""The world's per-step robot-obstacle collision test equals the clearance's sign.

``swept_disc_hits_obstacles`` replaces ``swept_obstacle_clearance(...) < 0`` in the step for speed (it
skips edges whose bounding box is farther than the radius from the path's and stops at the first hit).
"""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from socialnav import _core
from socialnav.maps.static_map import StaticMap

coord = st.floats(-4.0, 4.0, allow_nan=False, allow_infinity=False)
point = st.tuples(coord, coord)


@st.composite
def maps(draw) -> StaticMap:
    """1-4 walls and convex or non-convex polygons (squares and L blocks) anywhere in a 8 m square."""
    parts = []
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(["wall", "square", "l_block"]))
        x, y = draw(point)
        if kind == "wall":
            a, b = np.array([x, y]), np.array(draw(point))
            if np.hypot(*(b - a)) < 1e-3:
                b = a + 0.5
            parts.append(np.array([a, b]))
        else:
            s = draw(st.floats(0.2, 1.5))
            shape = ([[0, 0], [1, 0], [1, 1], [0, 1]] if kind == "square"
                     else [[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]])
            parts.append(np.array([x, y]) + s * np.array(shape, dtype=float))
    return StaticMap(tuple(parts))


def _both(static_map: StaticMap, start, end, radius: float) -> tuple[bool, bool]:
    vertices, offsets = static_map.to_flat()
    start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    clearance = _core.swept_obstacle_clearance(start, end, radius, vertices, offsets)
    return _core.swept_disc_hits_obstacles(start, end, radius, vertices, offsets), clearance < 0.0


@settings(max_examples=400, deadline=None)
@given(maps(), point, point, st.floats(0.0, 0.6))
def test_property_collision_test_equals_the_clearance_sign(static_map, start, end, radius):
    """Random maps, paths (crossing, touching, far) and radii: the same answer."""
    fast, reference = _both(static_map, start, end, radius)
    assert fast == reference


def test_hand_cases_near_the_culling_boundary():
    """Just clear, just touching, culled, crossing, and ending inside a polygon."""
    wall = StaticMap((np.array([[0.0, 0.0], [0.0, 2.0]]),))
    # Path parallel to the wall at 0.3 m: a disc of 0.3 m just touches only if the clearance is < 0.
    for radius, hits in ((0.29, False), (0.31, True)):
        assert _both(wall, (0.3, -1.0), (0.3, 3.0), radius) == (hits, hits)
    # Bounding boxes 1 m apart: culled, no hit.
    assert _both(wall, (1.3, 0.0), (1.3, 2.0), 0.3) == (False, False)
    # Crossing the wall within the step: a hit with any positive radius (clearance 0 - radius).
    assert _both(wall, (-0.5, 1.0), (0.5, 1.0), 0.01) == (True, True)
    # Ending inside a solid square (its edges farther than the radius from the end point): a hit.
    square = StaticMap((np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]]),))
    assert _both(square, (1.0, 1.0), (1.05, 1.0), 0.2) == (True, True)
    # Radius 0 inside: clearance 0 - 0 is not below 0.
    assert _both(square, (1.0, 1.0), (1.05, 1.0), 0.0) == (False, False)
