"""The closed-form rectangle test used by M_II agrees with the general polygon SAT."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from socialnav.metrics.comfort import rectangle_overlap_flags, rectangles_intersect, velocity_rectangles

coord = st.floats(-3.0, 3.0, allow_nan=False)
speed = st.floats(0.0, 2.0, allow_nan=False)
angle = st.floats(-np.pi, np.pi, allow_nan=False)
radius = st.floats(0.1, 0.6, allow_nan=False)


@settings(max_examples=400, deadline=None)
@given(coord, coord, speed, angle, radius, coord, coord, speed, angle, radius,
       st.sampled_from([0.5, 1.0, 2.0]), st.sampled_from(["rear", "front"]))
def test_closed_form_equals_polygon_sat(x1, y1, s1, a1, r1, x2, y2, s2, a2, r2, tau, anchor):
    p = np.array([[x1, y1], [x2, y2]])
    v = np.array([[s1 * np.cos(a1), s1 * np.sin(a1)], [s2 * np.cos(a2), s2 * np.sin(a2)]])
    r = np.array([r1, r2])
    corners, valid = velocity_rectangles(p, v, r, tau, anchor)
    expected = bool(rectangles_intersect(corners[0], corners[1]) and valid.all())
    fast = bool(rectangle_overlap_flags(p[0], v[0], r[0], p[1], v[1], r[1], tau, anchor))
    if expected != fast:
        # Only a configuration within rounding of touching may differ.
        gap_probe = [rectangle_overlap_flags(p[0], v[0], r[0], p[1], v[1], r[1], tau, anchor, tol=t)
                     for t in (-1e-9, 1e-9)]
        assert gap_probe[0] != gap_probe[1]


def test_touching_rectangles_intersect_and_separated_do_not():
    # Robot going +y from the origin (rectangle x in [-0.3, 0.3], y in [0, 1]); a human rectangle
    # whose left edge lies exactly on x = 0.3 touches it; 1 cm further it does not.
    args = (np.array([0.0, 0.0]), np.array([0.0, 1.0]), 0.3)
    touching = rectangle_overlap_flags(*args, np.array([0.6, 0.0]), np.array([0.0, 1.0]), 0.3, 1.0)
    apart = rectangle_overlap_flags(*args, np.array([0.61, 0.0]), np.array([0.0, 1.0]), 0.3, 1.0)
    stopped = rectangle_overlap_flags(*args, np.array([0.0, 0.5]), np.array([0.0, 0.0]), 0.3, 1.0)
    assert touching and not apart and not stopped
