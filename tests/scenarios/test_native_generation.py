"""The native generator (cpp/scenario_gen.cpp) must reproduce the Python generators bit for bit."""

import dataclasses

import numpy as np
import pytest

from socialnav.scenarios import episode_seeds, make_scenario
from socialnav.scenarios._placement import ScenarioGenerationError
from socialnav.scenarios.circle import CircleCrossing
from socialnav.scenarios.native import native_config

CASES = [
    ("circle_crossing", {}),
    ("circle_crossing", {"randomize_attributes": True, "n_humans": 8, "start_noise": 1.0}),
    ("circle_crossing", {"n_humans": 0}),
    ("random", {}),
    ("random", {"randomize_attributes": True, "n_humans": 12, "square_width": 9.0}),
    ("parallel_traffic", {}),
    ("parallel_traffic", {"traffic_area": "band", "band_width": 3.0}),
    ("perpendicular_traffic", {}),
    ("perpendicular_traffic", {"traffic_area": "band", "randomize_attributes": True}),
    ("square_crossing", {"discomfort_dist": 0.5}),
]


def bitwise_equal(a, b):
    assert a.keys() == b.keys()
    for name in a:
        x, y = a[name], b[name]
        assert x.dtype == y.dtype and x.shape == y.shape, name
        assert np.array_equal(x.view(np.uint8), y.view(np.uint8)), f"{name} differs"


@pytest.mark.parametrize(("name", "settings"), CASES)
@pytest.mark.parametrize("split", ["test", "train"])
def test_native_generation_is_bit_identical(name, settings, split):
    scenario = make_scenario(name, **settings)
    assert native_config(scenario) is not None
    indices = np.arange(1000) if split == "test" else np.arange(10_000, 12_000)
    seeds = episode_seeds(split, indices)
    native = scenario.generate(indices, seeds)
    python = scenario.generate(indices, seeds, native=False)
    bitwise_equal(native.arrays(), python.arrays())


@pytest.mark.parametrize(
    ("name", "settings"),
    [
        ("circle_crossing", {"randomize_attributes": True, "n_humans": 10}),  # fails at a start
        ("random", {"n_humans": 40, "square_width": 6.0}),  # fails at a goal
    ],
)
def test_impossible_scenes_raise_the_same_error(name, settings):
    scenario = make_scenario(name, **settings)
    indices = np.arange(1000)
    seeds = episode_seeds("test", indices)
    with pytest.raises(ScenarioGenerationError) as python:
        scenario.generate(indices, seeds, native=False)
    with pytest.raises(ScenarioGenerationError) as native:
        scenario.generate(indices, seeds)
    assert str(native.value) == str(python.value)
    assert "of human" in str(native.value) and "seeds" in str(native.value)


def test_subclasses_and_single_human_scenarios_keep_the_python_generator():
    @dataclasses.dataclass(frozen=True, kw_only=True)
    class Shifted(CircleCrossing):  # a user's scenario: draws its humans its own way
        name = "circle_crossing"

        def sample_humans(self, rng, indices):
            h = super().sample_humans(rng, indices)
            return h._replace(start=h.start + 0.5)

    assert native_config(Shifted()) is None
    batch = Shifted().generate(np.arange(3), episode_seeds("test", np.arange(3)))
    base = make_scenario("circle_crossing").generate(np.arange(3), episode_seeds("test", np.arange(3)))
    np.testing.assert_array_equal(batch.human_start, base.human_start + 0.5)
    for name in ("passing", "overtaking", "crossing"):
        assert native_config(make_scenario(name)) is None
