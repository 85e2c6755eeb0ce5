"""Scenario base class: common settings, the robot's set-up and batch generation.

A scenario is a frozen dataclass of settings (declared with `param`, validated by the settings
system, `socialnav.settings`) with a method ``generate(indices, seeds)`` that returns the initial
state of a batch of episodes (`EpisodeBatch`, see docs/internals.md). All randomness comes from
`EpisodeRandom` keyed by the episode seed and the scenario's registered name, so an episode depends
only on (scenario, settings, seed, index), never on the batch it is in. The episode seed scheme is
in `socialnav.scenarios.seeds`, the batch container in `socialnav.scenarios.episode_batch` (both
re-exported here).
"""

from __future__ import annotations

import abc
import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from socialnav.maps.static_map import StaticMap
from socialnav.scenarios._params import ParamSpec, param
from socialnav.scenarios.episode_batch import EpisodeBatch, HumanArrays
from socialnav.scenarios.episode_random import EpisodeRandom
from socialnav.scenarios.seeds import SPLIT_BASES, SPLIT_SIZE, as_indices, episode_seeds
from socialnav.settings import Settings

__all__ = [
    "SPLIT_BASES",
    "SPLIT_SIZE",
    "EpisodeBatch",
    "HumanArrays",
    "ParamSpec",
    "Scenario",
    "episode_seeds",
    "param",
]

# Key streams of `EpisodeRandom` draws. A draw's key starts with one of these so that, say, the
# attributes of human j never share numbers with the attempts at placing it.
STREAM_ATTRIBUTES = 1
STREAM_SIDE = 2
STREAM_START = 3
STREAM_GOAL = 4
STREAM_JITTER = 5


@dataclass(frozen=True, kw_only=True)
class Scenario(Settings, abc.ABC):
    """Base class of scenario generators: common settings and the robot's set-up.

    The robot starts at (0, −R) facing +y with goal (0, +R), R = `circle_radius`. Subclasses
    implement `sample_humans`, vectorised over the batch, drawing every random number from the
    `EpisodeRandom` they are given, with keys that name the human and the attempt, never the
    episode's position in the batch. Register them with ``@register_scenario(name)``.

    Settings are validated on construction: a bad value raises ConfigError, a ValueError
    (ConfigTypeError, also a TypeError, for a wrong type) naming the field and the value. Integers
    are accepted for float settings and lists for tuple settings (as YAML gives them) and converted.
    The parameter table (`parameters`) comes from the `param` declarations.
    """

    normalise: ClassVar[bool] = True
    name: ClassVar[str] = ""
    #: Whether `n_humans` may differ from its default (False for the single-human scenarios).
    fixed_n_humans: ClassVar[bool] = False

    n_humans: int = param(5, "humans per episode", ge=0)
    robot_radius: float = param(0.3, "robot radius", unit="m", gt=0)
    robot_v_pref: float = param(1.0, "robot preferred (maximum) speed", unit="m/s", gt=0)
    human_radius: float = param(0.3, "human radius (unless randomised)", unit="m", gt=0)
    human_v_pref: float = param(1.0, "human preferred speed (unless randomised)", unit="m/s", gt=0)
    randomize_attributes: bool = param(
        False, "draw each human's v_pref and radius from the ranges below (CrowdSim)"
    )
    random_v_pref_range: tuple[float, float] = param(
        (0.5, 1.5), "range of randomised human v_pref", unit="m/s"
    )
    random_radius_range: tuple[float, float] = param(
        (0.3, 0.5), "range of randomised human radius", unit="m"
    )
    discomfort_dist: float = param(
        0.2, "extra clearance required between placed starts (and goals)", unit="m", ge=0
    )
    circle_radius: float = param(
        4.0,
        "R: robot starts at (0, -R), goal (0, R); circle radius of circle_crossing",
        unit="m",
        gt=0,
    )
    max_attempts: int = param(
        1000, "redraws per human before the scene is declared impossible", gt=0
    )

    @classmethod
    def setting_owner(cls) -> str:
        """Errors name a scenario's settings by its class (``CircleCrossing.n_humans``)."""
        return cls.__name__

    def cross_check(self) -> None:
        """Checks the attribute ranges and, for fixed-size scenarios, `n_humans`.

        Raises:
            ConfigError: A range with low > high (or <= 0), or n_humans off its fixed value.
        """
        for name in ("random_v_pref_range", "random_radius_range"):
            low, high = getattr(self, name)
            if not 0 < low <= high:
                self.refuse(name, "must satisfy 0 < low <= high")
        if self.fixed_n_humans:
            default = next(f.default for f in dataclasses.fields(self) if f.name == "n_humans")
            if self.n_humans != default:
                self.refuse("n_humans", f"must be {default} for this scenario")

    # ---- public API -------------------------------------------------------------------------

    def settings(self) -> dict[str, Any]:
        """The resolved settings with a ``type`` key, ready to record beside results."""
        values = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        return {"type": self.name, **values}

    @property
    def n_episodes(self) -> int | None:
        """Number of distinct episodes per split, or None when unbounded."""
        return None

    def rng(self, seeds: np.ndarray) -> EpisodeRandom:
        """The scenario's counter-based random source for these seeds (salted by its name)."""
        if not self.name:
            raise TypeError(
                f"{type(self).__name__} has no registered name; decorate it with "
                "@register_scenario(name) (the name salts its random numbers)"
            )
        return EpisodeRandom(seeds, self.name)

    def generate(
        self,
        indices: np.ndarray | Sequence[int],
        seeds: np.ndarray | Sequence[int],
        *,
        native: bool = True,
    ) -> EpisodeBatch:
        """Generate the initial states of a batch of episodes.

        Args:
            indices: Episode indices within their split [(B,) int].
            seeds: Episode seeds [(B,) int64], usually ``episode_seeds(split, indices)``.
            native: Use the native generator where this exact scenario class has one (circle crossing
                and the square family; bit-identical to ``sample_humans``, ~20x faster); False always
                runs ``sample_humans``.

        Returns:
            A validated `EpisodeBatch` with N = `n_humans` slots, all real.

        Raises:
            ValueError: Mismatched or malformed indices / seeds, or an impossible scene.
        """
        idx = as_indices(indices)
        sd = as_indices(seeds)
        if idx.shape != sd.shape:
            raise ValueError(
                f"indices and seeds must have the same shape, got {idx.shape} and {sd.shape}"
            )
        if idx.size and idx.min() < 0:
            raise ValueError(f"episode indices must be >= 0, got {int(idx.min())}")
        b = idx.shape[0]
        from socialnav.scenarios.native import native_config, sample_humans_native

        config = native_config(self) if native else None
        if config is not None:
            humans = sample_humans_native(self, config, sd)
        else:
            humans = self.sample_humans(self.rng(sd), idx)
        n = self.n_humans
        shapes = {"start": (b, n, 2), "goal": (b, n, 2), "radius": (b, n), "v_pref": (b, n)}
        for key, shape in shapes.items():
            got = getattr(humans, key).shape
            if got != shape:
                raise ValueError(
                    f"{type(self).__name__}.sample_humans returned {key} of shape "
                    f"{got}, expected {shape}"
                )
        robot_start, robot_goal = (np.broadcast_to(np.asarray(p, dtype=np.float64), (b, 2)).copy()
                                   for p in self.robot_endpoints())
        heading = robot_goal - robot_start  # the robot starts facing its goal: π/2 for (0, -R) -> (0, R)
        theta = np.arctan2(heading[:, 1], heading[:, 0])
        if self.robot_heading() is not None:
            theta = np.full(b, float(self.robot_heading()))
        return EpisodeBatch(
            seeds=sd,
            indices=idx,
            robot_start=robot_start,
            robot_goal=robot_goal,
            robot_theta=theta,
            robot_radius=np.full(b, float(self.robot_radius)),
            robot_v_pref=np.full(b, float(self.robot_v_pref)),
            human_start=np.asarray(humans.start, dtype=np.float64),
            human_goal=np.asarray(humans.goal, dtype=np.float64),
            human_radius=np.asarray(humans.radius, dtype=np.float64),
            human_v_pref=np.asarray(humans.v_pref, dtype=np.float64),
            human_mask=np.ones((b, n), dtype=bool),
            static_maps=self.episode_maps(sd, idx),
        ).validate()

    def episode_maps(self, seeds: np.ndarray, indices: np.ndarray) -> tuple[StaticMap, ...] | None:
        """The static maps of the episodes of these seeds and indices, as :meth:`generate` draws them.

        A map depends on its episode's seed and index alone, so this gives an episode in flight its map
        back (a resumed training run) without generating the episode again.

        Args:
            seeds: The episodes' seeds [(B,) int].
            indices: Their indices within the split [(B,) int].

        Returns:
            One map per episode, or None on open floors.
        """
        if type(self).static_maps is Scenario.static_maps:
            return None  # open floor: no random source to build (generate runs on every world refill)
        return self.static_maps(self.rng(seeds), indices)

    def episodes(self, split: str, indices: np.ndarray | Sequence[int]) -> EpisodeBatch:
        """Generate episodes named by (split, index).

        Args:
            split: "val", "test" or "train".
            indices: Episode indices within the split [(B,) int].

        Returns:
            ``generate(indices, episode_seeds(split, indices))``.
        """
        return self.generate(indices, episode_seeds(split, indices))

    def robot_endpoints(self) -> tuple[np.ndarray, np.ndarray]:
        """The robot's start and goal [(2,) m each, or (B, 2)]: (0, −R) and (0, R) by default.

        The robot starts facing its goal.
        """
        r = self.circle_radius
        return np.array([0.0, -r]), np.array([0.0, r])

    def robot_heading(self) -> float | None:
        """The robot's initial heading [rad], or None: facing its goal (π/2 by default)."""
        return None

    def static_maps(self, rng: EpisodeRandom, indices: np.ndarray) -> tuple[StaticMap, ...] | None:
        """The obstacles of every episode (B maps, shared objects allowed), or None: an open floor.

        Scenarios with walls override this; the episodes' starts and goals must clear the map
        (``EpisodeBatch.validate`` checks). ``rng`` is the scenario's random source for the batch,
        for maps drawn per episode (use a key stream of its own).
        """
        return None

    @abc.abstractmethod
    def sample_humans(self, rng: EpisodeRandom, indices: np.ndarray) -> HumanArrays:
        """Draw the humans of every episode, vectorised over the batch.

        Args:
            rng: Random source over the batch's seeds [B rows].
            indices: Episode indices [(B,) int64] (used by scenarios laid out on a grid).

        Returns:
            `HumanArrays` with N = `n_humans`.
        """

    # ---- helpers for subclasses -------------------------------------------------------------

    def human_attributes(self, rng: EpisodeRandom, j: int) -> tuple[np.ndarray, np.ndarray]:
        """Radius and v_pref of human j in every episode, randomised if the setting asks.

        Args:
            rng: Random source [B rows].
            j: Human index (part of the draw's key).

        Returns:
            radius [(B,) m], v_pref [(B,) m/s].
        """
        b = len(rng)
        if not self.randomize_attributes:
            return np.full(b, float(self.human_radius)), np.full(b, float(self.human_v_pref))
        u = rng.random((STREAM_ATTRIBUTES, j), 2)
        # CrowdSim's Human.sample_random_attributes draws v_pref first, then the radius.
        lo, hi = self.random_v_pref_range
        v_pref = lo + (hi - lo) * u[:, 0]
        lo, hi = self.random_radius_range
        radius = lo + (hi - lo) * u[:, 1]
        return radius, v_pref
