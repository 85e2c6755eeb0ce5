"""Scenario generators (initial states of episodes) and their registry. Pure NumPy.

Example:
    >>> from socialnav.scenarios import make_scenario
    >>> batch = make_scenario("circle_crossing", n_humans=5).episodes("test", range(500))
    >>> batch.human_start.shape
    (500, 5, 2)

The built-in scenarios are `circle_crossing`, `random`, `parallel_traffic`,
`perpendicular_traffic`, `square_crossing`, `passing`, `overtaking` and `crossing`, and the
scenarios with walls after Francis et al. (`socialnav.scenarios.francis`; the pillars drawn per
episode: `socialnav.scenarios.circle_pillars`). Importing this package imports none of their
modules: the registry loads them the first time it is asked for a scenario (see
`socialnav.scenarios.registry`), and each scenario class below loads its module on first access.
Third-party scenarios plug in through the entry-point group ``socialnav.scenarios``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from socialnav._runtime import lazy_exports
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
from socialnav.scenarios.registry import (
    UnknownScenarioError,
    get_scenario,
    list_scenarios,
    make_scenario,
    register_scenario,
    scenario_from_settings,
)

#: Public names whose module loads on first use (see ``lazy_exports``).
_EXPORTS = {
    "CircleCrossing": "socialnav.scenarios.circle",
    "EpisodeRandom": "socialnav.scenarios.episode_random",
    "Crossing": "socialnav.scenarios.single",
    "Overtaking": "socialnav.scenarios.single",
    "Passing": "socialnav.scenarios.single",
    "ParallelTraffic": "socialnav.scenarios.square",
    "PerpendicularTraffic": "socialnav.scenarios.square",
    "RandomPlacement": "socialnav.scenarios.square",
    "SquareCrossing": "socialnav.scenarios.square",
}

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

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

if TYPE_CHECKING:  # what type checkers and IDEs see; at run time the names load lazily
    from socialnav.scenarios.circle import CircleCrossing
    from socialnav.scenarios.episode_random import EpisodeRandom
    from socialnav.scenarios.single import Crossing, Overtaking, Passing
    from socialnav.scenarios.square import (
        ParallelTraffic,
        PerpendicularTraffic,
        RandomPlacement,
        SquareCrossing,
    )
