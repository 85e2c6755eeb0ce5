"""Scenario generators (initial states of episodes) and their registry. Pure NumPy.

Example:
    >>> from socialnav.scenarios import make_scenario
    >>> batch = make_scenario("circle_crossing", n_humans=5).episodes("test", range(500))
    >>> batch.human_start.shape
    (500, 5, 2)

Importing this package registers the built-in scenarios: `circle_crossing`, `random`,
`parallel_traffic`, `perpendicular_traffic`, `square_crossing`, `passing`, `overtaking` and
`crossing`, and the scenarios with walls after Francis et al. (`socialnav.scenarios.francis`).
Third-party scenarios plug in through the entry-point group ``socialnav.scenarios``.
"""

from socialnav.scenarios import circle, francis, single, square  # noqa: F401  (registers the scenarios)
from socialnav.scenarios._placement import ScenarioGenerationError
from socialnav.scenarios.base import (
    SPLIT_BASES,
    EpisodeBatch,
    HumanArrays,
    ParamSpec,
    Scenario,
    episode_seeds,
    param,
)
from socialnav.scenarios.circle import CircleCrossing
from socialnav.scenarios.random import EpisodeRandom
from socialnav.scenarios.registry import (
    UnknownScenarioError,
    get_scenario,
    list_scenarios,
    make_scenario,
    register_scenario,
    scenario_from_settings,
)
from socialnav.scenarios.single import Crossing, Overtaking, Passing
from socialnav.scenarios.square import (
    ParallelTraffic,
    PerpendicularTraffic,
    RandomPlacement,
    SquareCrossing,
)

__all__ = [
    "SPLIT_BASES",
    "CircleCrossing",
    "Crossing",
    "EpisodeBatch",
    "EpisodeRandom",
    "HumanArrays",
    "Overtaking",
    "ParallelTraffic",
    "ParamSpec",
    "Passing",
    "PerpendicularTraffic",
    "RandomPlacement",
    "Scenario",
    "ScenarioGenerationError",
    "SquareCrossing",
    "UnknownScenarioError",
    "episode_seeds",
    "get_scenario",
    "list_scenarios",
    "make_scenario",
    "param",
    "register_scenario",
    "scenario_from_settings",
]
