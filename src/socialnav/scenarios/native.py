"""Native generation of the built-in multi-human scenarios (``cpp/scenario_gen.cpp``).

The native generator computes exactly what the Python ``sample_humans`` of circle crossing and the
square family compute (same counter-based random numbers, same arithmetic in the same order, the same
libm cos/sin), so the episodes are bit-identical (``tests/scenarios/test_native_generation.py``), about
20 times faster. `Scenario.generate` uses it for the exact built-in classes; a subclass (a user's
scenario deriving from a built-in one) may change how humans are drawn, so it keeps the Python path.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from socialnav.scenarios._placement import ScenarioGenerationError, failure_message
from socialnav.scenarios.base import HumanArrays
from socialnav.scenarios.episode_random import _GOLDEN, _fmix_int, salt_hash

if TYPE_CHECKING:
    from socialnav.scenarios.base import Scenario

try:
    from socialnav import _core
except ImportError:  # pragma: no cover - a source tree without the compiled core
    _core = None  # type: ignore[assignment]  # callers check for None: the Python generators run instead

__all__ = ["native_config", "raise_on_failure", "sample_humans_native"]


def native_config(scenario: Scenario):
    """The native generator's settings for ``scenario``, or None when it has no native generator."""
    if _core is None:
        return None
    kind = type(scenario).__dict__.get("_native_kind")
    if kind is None:  # only the exact built-in classes: a subclass may draw its humans differently
        return None
    c = _core.ScenarioConfig()
    c.kind = getattr(_core, kind)
    c.n_humans = scenario.n_humans
    c.salt_prefix = _fmix_int(salt_hash(scenario.name) + _GOLDEN)
    c.robot_radius = scenario.robot_radius
    c.robot_v_pref = scenario.robot_v_pref
    c.human_radius = scenario.human_radius
    c.human_v_pref = scenario.human_v_pref
    c.randomize_attributes = scenario.randomize_attributes
    c.v_pref_low, c.v_pref_high = scenario.random_v_pref_range
    c.radius_low, c.radius_high = scenario.random_radius_range
    c.discomfort_dist = scenario.discomfort_dist
    c.circle_radius = scenario.circle_radius
    c.max_attempts = scenario.max_attempts
    for name in ("start_noise", "square_width", "band_width"):
        if hasattr(scenario, name):
            setattr(c, name, getattr(scenario, name))
    if hasattr(scenario, "traffic_area"):
        c.band = scenario.traffic_area == "band"
        c.flow_axis = type(scenario).flow_axis  # type: ignore[attr-defined]  # the traffic scenarios' class constant
    return c


def sample_humans_native(scenario: Scenario, config, seeds: np.ndarray) -> HumanArrays:
    """``scenario.sample_humans`` for the episodes of ``seeds``, computed by the native generator.

    Raises:
        ScenarioGenerationError: as the Python generator, naming the same quantity and episodes.
    """
    b, n = seeds.shape[0], scenario.n_humans
    start = np.zeros((b, n, 2))
    goal = np.zeros((b, n, 2))
    radius = np.zeros((b, n))
    v_pref = np.zeros((b, n))
    failure = np.zeros(b, dtype=np.int32)
    _core.generate_humans(
        config, np.ascontiguousarray(seeds, dtype=np.int64), start, goal, radius, v_pref, failure
    )
    raise_on_failure(scenario, failure, seeds)
    return HumanArrays(start=start, goal=goal, radius=radius, v_pref=v_pref)


def raise_on_failure(scenario: Scenario, failure: np.ndarray, seeds: np.ndarray) -> None:
    """Raises the Python generator's error for the native failure codes, if any episode failed.

    The Python generator stops at the first quantity (human j's start, then its goal) that some episode
    cannot place, and names every episode failing there.
    """
    if not failure.any():
        return
    first = int(failure[failure > 0].min())
    j, what = (first - 1) // 2, "start" if first % 2 == 1 else "goal"
    raise ScenarioGenerationError(
        failure_message(
            f"{scenario.name}: {what} of human {j}", scenario.max_attempts, seeds[failure == first]
        )
    )
