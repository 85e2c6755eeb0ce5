"""StaticMap: validation, orientation, flat layout and distances against hand-computed values."""

import numpy as np
import pytest

from socialnav.maps.static_map import MapError, StaticMap


def test_clockwise_square_is_stored_counter_clockwise():
    cw = [[0, 0], [0, 1], [1, 1], [1, 0]]
    m = StaticMap((cw,))
    v = m.polygons[0]
    area = 0.5 * np.sum(v[:, 0] * np.roll(v[:, 1], -1) - np.roll(v[:, 0], -1) * v[:, 1])
    assert area == pytest.approx(1.0)


def test_flat_round_trip():
    m = StaticMap(([[0, 0], [2, 0]], [[0, 1], [1, 1], [1, 2]]))
    verts, offs = m.to_flat()
    assert verts.shape == (5, 2) and offs.tolist() == [0, 2, 5]
    assert StaticMap.from_flat(verts, offs) == m
    assert StaticMap.from_dict(m.to_dict()) == m


def test_distance_hand_computed():
    m = StaticMap(([[0, 0], [2, 0]], [[5, 5], [6, 5], [6, 6], [5, 6]]))
    d = m.distance(np.array([[1.0, 3.0], [3.0, 0.0], [5.5, 5.5], [7.0, 5.5]]))
    np.testing.assert_allclose(d, [3.0, 1.0, 0.0, 1.0])
    assert np.isinf(StaticMap().distance(np.zeros((3, 2)))).all()


@pytest.mark.parametrize(
    "poly, match",
    [
        ([[0, 0], [np.nan, 1]], "vertex 1 is not finite"),
        ([[0, 0], [0, 0]], "coincide"),
        ([[0, 0], [1, 1], [1, 0], [0, 1]], "self-intersecting"),
        ([[0, 0], [1, 0], [2, 0]], "zero area"),
        ([[0, 0]], "k >= 2"),
    ],
)
def test_bad_polygons_name_the_problem(poly, match):
    with pytest.raises(MapError, match=match):
        StaticMap((poly,))


@pytest.mark.parametrize("data, found", [
    ({"polygon": [[[0, 0], [1, 0]]]}, "found unknown key(s) 'polygon'"),
    ({"polygons": [], "units": "cm"}, "found unknown key(s) 'units'"),
    ({}, "found no keys"),
])
def test_from_dict_names_the_keys_it_does_not_know(data, found):
    with pytest.raises(MapError) as info:
        StaticMap.from_dict(data)
    expected = "map: expected a mapping with one key, 'polygons' (a list of vertex lists); "
    assert str(info.value) == expected + found


def test_a_file_name_given_as_polygons_points_to_load_map():
    with pytest.raises(MapError, match=r"StaticMap takes polygons, not a file \('walls.yaml'\): read a map "
                       r"file with socialnav.maps.load_map"):
        StaticMap("walls.yaml")


@pytest.mark.parametrize(("given", "match"), [
    ({"polygons": []}, r"not a dict: StaticMap.from_dict reads the dict form .*got keys \['polygons'\]"),
    (None, r"a sequence of polygons \(vertex lists\), got NoneType None; an open floor is StaticMap\(\)"),
    (5, r"got int 5"),
])
def test_what_is_not_a_sequence_of_polygons_is_named(given, match):
    with pytest.raises(MapError, match=match):
        StaticMap(given)
