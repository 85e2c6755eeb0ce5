"""The scenarios' output: `EpisodeBatch`, the initial states of B episodes, and `HumanArrays`.

Its fields, shapes and units are the contract between scenarios and the world (docs/internals.md,
"EpisodeBatch"); `EpisodeBatch.validate` checks them, obstacles included.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from socialnav.maps.static_map import MapStack, StaticMap

__all__ = ["EpisodeBatch", "HumanArrays"]

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

    def _which(self, row: int) -> str:
        """An episode of the batch as messages name it: its index, seed and row."""
        return f"episode {int(self.indices[row])} (seed {int(self.seeds[row])}, row {row} of the batch)"

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
        # positions first: a NaN goal makes the heading derived from it NaN too, and is the one to name
        for name in _B2_FIELDS + _BN2_FIELDS + _B_FIELDS[2:] + _BN_FIELDS:
            arr = getattr(self, name)
            if arr.dtype != np.float64:
                raise ValueError(f"EpisodeBatch.{name} must be float64, got {arr.dtype}")
            if not np.all(np.isfinite(arr)):
                row = int(np.flatnonzero(~np.all(np.isfinite(arr.reshape(b, -1)), axis=1))[0])
                raise ValueError(f"EpisodeBatch.{name} contains non-finite values: {self._which(row)} has "
                                 f"{arr[row].tolist()}")
        for name in ("robot_radius", "robot_v_pref"):
            bad = np.flatnonzero(getattr(self, name) <= 0)
            if bad.size:
                raise ValueError(f"EpisodeBatch.{name} must be > 0: {self._which(int(bad[0]))} has "
                                 f"{getattr(self, name)[bad[0]]}")
        mask = self.human_mask
        for name in _BN_FIELDS:
            arr = getattr(self, name)
            bad = np.argwhere((arr <= 0) & mask)
            if bad.size:
                raise ValueError(f"EpisodeBatch.{name} must be > 0 for real humans: "
                                 f"{self._which(int(bad[0][0]))}, human {int(bad[0][1])} has "
                                 f"{arr[bad[0][0], bad[0][1]]}")
        for name in _BN2_FIELDS + _BN_FIELDS:
            if np.any(getattr(self, name)[~mask] != 0):
                raise ValueError(f"EpisodeBatch.{name} must be 0 in padded slots")
        self._validate_starts()
        if self.static_maps is not None:
            self._validate_maps()
        return self

    def _validate_starts(self) -> None:
        """No two agents start overlapping: the episode would open with a collision nobody caused."""
        mask = self.human_mask
        starts, radii = self.human_start, self.human_radius
        # a margin far below any placement, far above rounding: touching discs are allowed
        slack = 1e-9
        to_robot = np.linalg.norm(starts - self.robot_start[:, None, :], axis=-1)
        bad = np.argwhere(mask & (to_robot < (radii + self.robot_radius[:, None]) * (1.0 - slack)))
        if bad.size:
            row, human = (int(i) for i in bad[0])
            raise ValueError(f"EpisodeBatch: {self._which(row)}: human {human} starts overlapping the robot "
                             f"(centres {to_robot[row, human]:.4g} m apart, radii {radii[row, human]:g} + "
                             f"{self.robot_radius[row]:g} m)")
        if starts.shape[1] < 2:
            return
        gap = np.linalg.norm(starts[:, :, None, :] - starts[:, None, :, :], axis=-1)
        both = mask[:, :, None] & mask[:, None, :]
        upper = np.triu(np.ones(gap.shape[1:], dtype=bool), k=1)
        bad = np.argwhere(both & upper & (gap < (radii[:, :, None] + radii[:, None, :]) * (1.0 - slack)))
        if bad.size:
            row, i, j = (int(k) for k in bad[0])
            raise ValueError(f"EpisodeBatch: {self._which(row)}: humans {i} and {j} start overlapping "
                             f"(centres {gap[row, i, j]:.4g} m apart, radii {radii[row, i]:g} + "
                             f"{radii[row, j]:g} m)")

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
        """Checks that the starts and goals of episodes ``idx`` clear their obstacles.

        Args:
            idx: Episode rows [(E,) int].
            distance: ``distance(points)`` to the obstacles, points of shape (E, M, 2) [m].

        Raises:
            ValueError: Naming the first covered start or goal.
        """
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
