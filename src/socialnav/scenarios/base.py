"""Scenario base class, the `EpisodeBatch` it produces, and the episode seed scheme.

A scenario is a frozen dataclass of settings with a method ``generate(indices, seeds)`` that
returns the initial state of a batch of episodes (see docs/internals.md, "EpisodeBatch"). All
randomness comes from `EpisodeRandom` keyed by the episode seed and the scenario's registered name,
so an episode depends only on (scenario, settings, seed, index), never on the batch it is in.
"""

from __future__ import annotations

import abc
import dataclasses
import functools
import typing
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, NamedTuple

import numpy as np

from socialnav.scenarios._params import ParamSpec, check_value, param, type_name
from socialnav.scenarios.random import EpisodeRandom
from socialnav.static_map import MapStack, StaticMap

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


@functools.cache
def _type_hints(cls: type) -> dict[str, Any]:
    """A settings class's resolved annotations, computed once per class (resolving them costs ≈ 0.5 ms,
    and settings are built for every chunk of a sweep and every episode stream)."""
    return typing.get_type_hints(cls)


SPLIT_BASES: dict[str, int] = {"val": 0, "test": 1000, "train": 2000}
"""First seed of each split (CrowdNav's scheme: val 0 + i, test 1000 + i, train from 2000 on)."""
#: Largest number of val / test episodes per scenario that keeps the splits' seeds disjoint.
SPLIT_SIZE = 1000

# Key streams of `EpisodeRandom` draws. A draw's key starts with one of these so that, say, the
# attributes of human j never share numbers with the attempts at placing it.
STREAM_ATTRIBUTES = 1
STREAM_SIDE = 2
STREAM_START = 3
STREAM_GOAL = 4
STREAM_JITTER = 5


def episode_seeds(split: str, indices: np.ndarray | Sequence[int] | int) -> np.ndarray:
    """Seeds of the episodes ``indices`` of a split: ``SPLIT_BASES[split] + index``.

    Validation and test indices must lie in [0, 1000) so the splits never share a seed; training
    indices are unbounded (seeds 2000 and up).

    Args:
        split: "val", "test" or "train".
        indices: Episode indices within the split [(B,) int, or a scalar].

    Returns:
        Seeds [(B,) int64].

    Raises:
        ValueError: Unknown split, or an index outside the split's range.
    """
    if split not in SPLIT_BASES:
        valid = ", ".join(repr(s) for s in SPLIT_BASES)
        raise ValueError(f"unknown split {split!r}; valid splits: {valid}")
    idx = _as_indices(indices, copy=False)  # only read here (a world's refill calls this every step)
    if idx.size and idx.min() < 0:
        raise ValueError(f"episode indices must be >= 0, got {int(idx.min())}")
    if split != "train" and idx.size and idx.max() >= SPLIT_SIZE:
        raise ValueError(
            f"split {split!r} holds indices 0..{SPLIT_SIZE - 1} (seeds would overlap the next "
            f"split); got index {int(idx.max())}"
        )
    return SPLIT_BASES[split] + idx


def _as_indices(indices: np.ndarray | Sequence[int] | int, copy: bool = True) -> np.ndarray:
    """``indices`` checked as a 1-D int64 array; ``copy=False`` returns an int64 input itself (for
    callers that only read it)."""
    if type(indices) is np.ndarray and indices.dtype == np.int64 and indices.ndim == 1:
        return indices.copy() if copy else indices  # the common case (a world's refill, every step)
    arr = np.atleast_1d(np.asarray(indices))
    if arr.ndim != 1:
        raise ValueError(f"indices must be 1-D, got shape {arr.shape}")
    if arr.size == 0:
        return arr.astype(np.int64, copy=copy)
    if not np.issubdtype(arr.dtype, np.integer):
        raise TypeError(f"indices must be integers, got dtype {arr.dtype}")
    return arr.astype(np.int64, copy=copy)


# --------------------------------------------------------------------------------------------
# EpisodeBatch
# --------------------------------------------------------------------------------------------

_B_FIELDS = ("seeds", "indices", "robot_theta", "robot_radius", "robot_v_pref")
_B2_FIELDS = ("robot_start", "robot_goal")
_BN2_FIELDS = ("human_start", "human_goal")
_BN_FIELDS = ("human_radius", "human_v_pref")


@dataclass(frozen=True, eq=False)
class EpisodeBatch:
    """Initial states of B episodes with up to N humans each (padded, see `human_mask`).

    Units are SI. Padded human slots hold zeros. Arrays are float64 unless noted.

    Attributes:
        seeds: Episode seeds [(B,) int64].
        indices: Episode indices within their split [(B,) int64].
        robot_start: Robot start position [(B, 2) m].
        robot_goal: Robot goal position [(B, 2) m].
        robot_theta: Initial robot heading [(B,) rad]; π/2 faces +y.
        robot_radius: [(B,) m].
        robot_v_pref: Robot preferred (maximum) speed [(B,) m/s].
        human_start: Human start positions [(B, N, 2) m].
        human_goal: Human goal positions [(B, N, 2) m].
        human_radius: [(B, N) m].
        human_v_pref: Human preferred speeds [(B, N) m/s].
        human_mask: Real human slots [(B, N) bool].
        static_maps: The obstacles of each episode (B StaticMaps; an empty one is an open floor), or
            None when every episode is on an open floor (the original protocol). Episodes often share
            one map object.
    """

    seeds: np.ndarray
    indices: np.ndarray
    robot_start: np.ndarray
    robot_goal: np.ndarray
    robot_theta: np.ndarray
    robot_radius: np.ndarray
    robot_v_pref: np.ndarray
    human_start: np.ndarray
    human_goal: np.ndarray
    human_radius: np.ndarray
    human_v_pref: np.ndarray
    human_mask: np.ndarray
    static_maps: tuple[StaticMap, ...] | None = None

    @property
    def batch_size(self) -> int:
        """Number of episodes B."""
        return int(self.seeds.shape[0])

    @property
    def max_humans(self) -> int:
        """Number of human slots N (the padded width)."""
        return int(self.human_mask.shape[1])

    @property
    def n_humans(self) -> np.ndarray:
        """Number of real humans per episode [(B,) int64]."""
        return self.human_mask.sum(axis=1).astype(np.int64)

    def __len__(self) -> int:
        """Number of episodes B."""
        return self.batch_size

    def arrays(self) -> dict[str, np.ndarray]:
        """All array fields as a name → array dict (no copies); ``static_maps`` is not an array."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name != "static_maps"}

    def static_map(self, i: int) -> StaticMap | None:
        """The obstacles of episode ``i``, or None on an open floor."""
        if self.static_maps is None:
            return None
        smap = self.static_maps[i]
        return smap if smap else None

    def validate(self) -> EpisodeBatch:
        """Check shapes, dtypes, finiteness, positivity and zero padding.

        Returns:
            self, so that ``batch.validate()`` can be chained.

        Raises:
            ValueError: Naming the first offending field.
        """
        b = self.batch_size
        if self.human_mask.ndim != 2 or self.human_mask.shape[0] != b:
            raise ValueError(f"human_mask must have shape (B={b}, N), got {self.human_mask.shape}")
        n = self.max_humans
        expected = {name: (b,) for name in _B_FIELDS}
        expected.update({name: (b, 2) for name in _B2_FIELDS})
        expected.update({name: (b, n, 2) for name in _BN2_FIELDS})
        expected.update({name: (b, n) for name in _BN_FIELDS})
        for name, shape in expected.items():
            arr = getattr(self, name)
            if not isinstance(arr, np.ndarray) or arr.shape != shape:
                got = getattr(arr, "shape", type(arr).__name__)
                raise ValueError(f"EpisodeBatch.{name} must have shape {shape}, got {got}")
        for name in ("seeds", "indices"):
            if getattr(self, name).dtype != np.int64:
                dtype = getattr(self, name).dtype
                raise ValueError(f"EpisodeBatch.{name} must be int64, got {dtype}")
        if self.human_mask.dtype != np.bool_:
            raise ValueError(f"EpisodeBatch.human_mask must be bool, got {self.human_mask.dtype}")
        for name in _B_FIELDS[2:] + _B2_FIELDS + _BN2_FIELDS + _BN_FIELDS:
            arr = getattr(self, name)
            if arr.dtype != np.float64:
                raise ValueError(f"EpisodeBatch.{name} must be float64, got {arr.dtype}")
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"EpisodeBatch.{name} contains non-finite values")
        for name in ("robot_radius", "robot_v_pref"):
            if np.any(getattr(self, name) <= 0):
                raise ValueError(f"EpisodeBatch.{name} must be > 0")
        mask = self.human_mask
        for name in _BN_FIELDS:
            arr = getattr(self, name)
            if np.any(arr[mask] <= 0):
                raise ValueError(f"EpisodeBatch.{name} must be > 0 for real humans")
        for name in _BN2_FIELDS + _BN_FIELDS:
            if np.any(getattr(self, name)[~mask] != 0):
                raise ValueError(f"EpisodeBatch.{name} must be 0 in padded slots")
        if self.static_maps is not None:
            self._validate_maps()
        return self

    def _validate_maps(self) -> None:
        """Every map a StaticMap, and no start or goal covered by an obstacle (distance < radius)."""
        maps = self.static_maps
        if not isinstance(maps, tuple) or len(maps) != self.batch_size:
            got = len(maps) if isinstance(maps, (tuple, list)) else type(maps).__name__
            raise ValueError(f"EpisodeBatch.static_maps must be a tuple of {self.batch_size} StaticMaps, "
                             f"got {got}")
        for i, smap in enumerate(maps):
            if not isinstance(smap, StaticMap):
                raise ValueError(f"EpisodeBatch.static_maps[{i}] must be a StaticMap, "
                                 f"got {type(smap).__name__}")
        # one query per distinct map object when episodes share maps, one stacked query otherwise
        groups: dict[int, list[int]] = {}
        for i, smap in enumerate(maps):
            if smap:
                groups.setdefault(id(smap), []).append(i)
        if len(groups) > 8:
            walled = [i for rows in groups.values() for i in rows]
            self._check_clear(np.array(walled), MapStack([maps[i] for i in walled]).distance)
            return
        for rows in groups.values():
            self._check_clear(np.array(rows), maps[rows[0]].distance)

    def _check_clear(self, idx: np.ndarray, distance: Any) -> None:
        """Starts and goals of episodes ``idx`` clear of their obstacles (``distance(points)`` with
        points of shape (len(idx), M, 2))."""
        rows = idx.tolist()
        points = {
            "robot_start": (self.robot_start[idx][:, None], self.robot_radius[idx][:, None]),
            "robot_goal": (self.robot_goal[idx][:, None], self.robot_radius[idx][:, None]),
            "human_start": (self.human_start[idx], self.human_radius[idx]),
            "human_goal": (self.human_goal[idx], self.human_radius[idx]),
        }
        for name, (pts, radius) in points.items():
            real = self.human_mask[idx] if name.startswith("human") else np.ones(radius.shape, bool)
            dist = distance(pts)
            bad = (dist < radius) & real
            if bad.any():
                e, a = (int(v) for v in np.argwhere(bad)[0])
                who = "" if name.startswith("robot") else f", human {a}"
                raise ValueError(
                    f"EpisodeBatch.{name}: episode {rows[e]} (seed {int(self.seeds[rows[e]])}){who}: "
                    f"{pts[e, a].tolist()} is covered by an obstacle (distance "
                    f"{float(dist[e, a]):.3g} m < radius {float(radius[e, a]):.3g} m)")

    def take(self, idx: np.ndarray | Sequence[int] | slice) -> EpisodeBatch:
        """Select episodes along the batch axis.

        Args:
            idx: Integer indices, boolean mask [(B,)] or slice.

        Returns:
            A new batch with the selected episodes (N unchanged).
        """
        if not isinstance(idx, slice):
            idx = np.asarray(idx)
            if idx.ndim == 0:
                idx = idx[None]
        maps = None
        if self.static_maps is not None:
            picked = np.arange(self.batch_size)[idx]
            maps = tuple(self.static_maps[int(i)] for i in picked)
        return EpisodeBatch(**{k: v[idx] for k, v in self.arrays().items()}, static_maps=maps)

    @staticmethod
    def concat(batches: Sequence[EpisodeBatch]) -> EpisodeBatch:
        """Concatenate batches along the batch axis, padding to the largest N.

        Args:
            batches: One or more batches.

        Returns:
            A batch of size sum(B_k) with N = max(N_k).
        """
        if not batches:
            raise ValueError("EpisodeBatch.concat needs at least one batch")
        n = max(bt.max_humans for bt in batches)
        out: dict[str, list[np.ndarray]] = {name: [] for name in batches[0].arrays()}
        maps = None
        if any(bt.static_maps is not None for bt in batches):
            # open-floor batches beside walled ones: an empty map per episode
            open_floor = StaticMap()
            maps = tuple(m for bt in batches
                         for m in (bt.static_maps or (open_floor,) * bt.batch_size))
        for bt in batches:
            pad = n - bt.max_humans
            for name, arr in bt.arrays().items():
                if name.startswith("human_") and pad:
                    widths = [(0, 0)] * arr.ndim
                    widths[1] = (0, pad)
                    arr = np.pad(arr, widths)  # zeros / False, as padding requires
                out[name].append(arr)
        return EpisodeBatch(**{k: np.concatenate(v, axis=0) for k, v in out.items()}, static_maps=maps)


class HumanArrays(NamedTuple):
    """What `Scenario.sample_humans` returns for B episodes and N humans.

    Attributes:
        start: [(B, N, 2) m].
        goal: [(B, N, 2) m].
        radius: [(B, N) m].
        v_pref: [(B, N) m/s].
    """

    start: np.ndarray
    goal: np.ndarray
    radius: np.ndarray
    v_pref: np.ndarray


# --------------------------------------------------------------------------------------------
# Scenario
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class Scenario(abc.ABC):
    """Base class of scenario generators: common settings and the robot's set-up.

    The robot starts at (0, −R) facing +y with goal (0, +R), R = `circle_radius`. Subclasses
    implement `sample_humans`, vectorised over the batch, drawing every random number from the
    `EpisodeRandom` they are given, with keys that name the human and the attempt, never the
    episode's position in the batch. Register them with ``@register_scenario(name)``.

    Settings are validated on construction: a bad value raises ValueError (or TypeError) naming
    the field and the value. Integers are accepted for float settings and lists for tuple
    settings (as YAML gives them) and converted.
    """

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

    def __post_init__(self) -> None:
        """Validate and normalise every setting from its annotation and `param` metadata."""
        hints = _type_hints(type(self))
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            new = check_value(type(self).__name__, f.name, value, hints[f.name], f.metadata)
            if new is not value:
                object.__setattr__(self, f.name, new)
        for name in ("random_v_pref_range", "random_radius_range"):
            low, high = getattr(self, name)
            if not 0 < low <= high:
                raise ValueError(
                    f"{type(self).__name__}.{name} must satisfy 0 < low <= high, "
                    f"got {getattr(self, name)!r}"
                )
        if self.fixed_n_humans:
            default = next(f.default for f in dataclasses.fields(self) if f.name == "n_humans")
            if self.n_humans != default:
                raise ValueError(
                    f"{type(self).__name__}.n_humans must be {default} for this scenario, "
                    f"got {self.n_humans}"
                )

    # ---- public API -------------------------------------------------------------------------

    @classmethod
    def parameters(cls) -> tuple[ParamSpec, ...]:
        """The parameter table: name, default, type, doc, unit, choices of every setting."""
        hints = _type_hints(cls)
        rows = []
        for f in dataclasses.fields(cls):
            tp = hints[f.name]
            rows.append(
                ParamSpec(
                    name=f.name,
                    default=f.default,
                    type=type_name(tp),
                    doc=f.metadata.get("doc", ""),
                    unit=f.metadata.get("unit", ""),
                    choices=f.metadata.get("choices"),
                )
            )
        return tuple(rows)

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
        idx = _as_indices(indices)
        sd = _as_indices(seeds)
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
            static_maps=self._episode_maps(sd, idx),
        ).validate()

    def _episode_maps(self, seeds: np.ndarray, indices: np.ndarray) -> tuple[StaticMap, ...] | None:
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
