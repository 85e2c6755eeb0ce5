"""The Trajectory type: the contract between simulation and evaluation.

A :class:`Trajectory` holds one episode as time-major arrays (see ``docs/internals.md``). Metrics are
pure functions of it, so simulated episodes, real robot logs and pedestrian datasets are scored by the
same code. :func:`write_trajectories` / :func:`read_trajectories` store many episodes in one long
table (one row per episode, sample and agent) as Parquet or CSV; the column schema is documented in
``docs/trajectory_format.md``. The IO lives in :mod:`socialnav.trajectory_io` and is re-exported here;
``pyarrow`` is imported only when a file is read or written.

Sample 0 is the initial state and sample k the state after step k, at time t_k = k·dt. Continuation
samples (``continuation``, used by M_III) follow the episode: continuation row m (0-based) is the state
after step K + m + 1, at time (K + m + 1)·dt, with the robot parked where it reached its goal (within
its radius of it).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from socialnav.maps.static_map import StaticMap

__all__ = [
    "OUTCOMES",
    "ROLES",
    "AssumedValueWarning",
    "Trajectory",
    "TrajectoryFormatError",
    "read_trajectories",
    "write_trajectories",
]

OUTCOMES: tuple[str, ...] = ("success", "collision", "timeout", "unknown")
"""Allowed values of :attr:`Trajectory.outcome`; ``unknown`` is for logs."""

ROLES: tuple[str, ...] = ("robot", "human")
"""Allowed values of :attr:`Trajectory.roles`; agent 0 is always the robot."""


class AssumedValueWarning(UserWarning):
    """A value the data did not give was assumed (e.g. goals taken as the last positions).

    Issued by :meth:`Trajectory.from_positions` and the log importers, so that no default changes a
    score without a word; the message names every assumed value.
    """


class TrajectoryFormatError(ValueError):
    """A trajectory file or array does not follow the documented schema.

    Messages name the file, the column and the row (1-based data row, header excluded) where the
    problem was found, so that a hand-written log can be fixed without guessing.
    """


def _frozen_array(value: Any, name: str, shape: tuple[int | None, ...]) -> np.ndarray:
    """Copy ``value`` to a read-only float64 array and check its shape (None = any length)."""
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"Trajectory.{name}: cannot convert to a float array ({exc})") from exc
    mismatch = arr.ndim != len(shape) or any(
        s is not None and s != n for s, n in zip(shape, arr.shape, strict=True)
    )
    if mismatch:
        want = "(" + ", ".join("*" if s is None else str(s) for s in shape) + ")"
        raise ValueError(f"Trajectory.{name}: expected shape {want}, got {arr.shape}")
    arr.setflags(write=False)
    return arr


def _require_finite(arr: np.ndarray, name: str, hint: str = "") -> None:
    if not np.isfinite(arr).all():
        bad = tuple(int(i) for i in np.argwhere(~np.isfinite(arr))[0])
        raise ValueError(f"Trajectory.{name}: non-finite value {float(arr[bad])} at index {bad}{hint}")


@dataclass(frozen=True, eq=False)
class Trajectory:
    """One episode of one robot among humans, time-major (see ``docs/internals.md``).

    Arrays are copied to read-only float64 on construction, so a Trajectory can be shared safely.

    Attributes:
        dt: Step length [s], > 0.
        positions: Agent positions [m], shape (K+1, A, 2); agent 0 is the robot.
        velocities: Velocity applied during step k [m/s], shape (K+1, A, 2); sample 0 holds the
            initial velocity. Metrics use velocities executed between samples, (p_k − p_{k−1})/dt.
        radii: Agent radii [m], shape (A,).
        v_pref: Preferred speeds [m/s], shape (A,); NaN where unknown (logs, pedestrian data).
        goals: Goal each agent had at reset [m], shape (A, 2).
        roles: "robot" for agent 0, "human" for the others, shape (A,).
        outcome: One of ``OUTCOMES``.
        min_clearance: Simulator's swept minimum robot–human clearance per step [m], shape (K,), or
            None when not available (logs).
        continuation: Positions after the robot's episode, the robot parked where it reached its goal [m],
            shape (M, A, 2), or None. Row m is at time (K + m + 1)·dt.
        human_overlaps: Human–human overlap count reported by the simulator, or None.
        settings: Free-form settings (scenario, split, index, seed, visibility, human_model, policy,
            information, ...), JSON-serialisable.
        present: Presence mask, shape (K+1, A) bool, or None when every agent is present at every
            sample. Agents entering or leaving the scene (logs) are absent (False) outside their
            track; their positions and velocities there are NaN, never invented. The robot (agent 0)
            must be present at every sample. All-True masks are stored as None.
        arrival_times: Known time [s since sample 0] at which each agent reached its goal, shape (A,),
            NaN where unknown (M_III then detects arrival from the positions), or None.
        static_map: The episode's obstacles (:class:`~socialnav.maps.static_map.StaticMap`), or None for
            an open floor. An empty map is stored as None.
    """

    dt: float
    positions: np.ndarray
    velocities: np.ndarray
    radii: np.ndarray
    v_pref: np.ndarray
    goals: np.ndarray
    roles: tuple[str, ...]
    outcome: str = "unknown"
    min_clearance: np.ndarray | None = None
    continuation: np.ndarray | None = None
    human_overlaps: int | None = None
    settings: dict[str, Any] = field(default_factory=dict)
    present: np.ndarray | None = None
    arrival_times: np.ndarray | None = None
    static_map: StaticMap | None = None

    def __post_init__(self) -> None:
        set_ = object.__setattr__  # frozen: normalise fields once, here
        dt = float(self.dt)
        if not np.isfinite(dt) or dt <= 0.0:
            raise ValueError(f"Trajectory.dt: must be finite and > 0, got {self.dt!r}")
        set_(self, "dt", dt)
        pos = _frozen_array(self.positions, "positions", (None, None, 2))
        n_samples, n_agents = pos.shape[:2]
        if n_samples < 1 or n_agents < 1:
            raise ValueError(f"Trajectory.positions: need >= 1 sample and >= 1 agent, got {pos.shape}")
        vel = _frozen_array(self.velocities, "velocities", (n_samples, n_agents, 2))
        present = self._check_present(n_samples, n_agents)
        if present is not None:
            # absent samples hold NaN so that no metric can use a value the data never had
            pos, vel = pos.copy(), vel.copy()
            pos[~present], vel[~present] = np.nan, np.nan
            pos.setflags(write=False)
            vel.setflags(write=False)
            _require_finite(pos[present], "positions (where present)")
            _require_finite(vel[present], "velocities (where present)")
        else:
            absent = " (an agent absent at some samples: pass present=, a (K+1, A) mask, with NaN there)"
            _require_finite(pos, "positions", absent)
            _require_finite(vel, "velocities", absent)
        set_(self, "present", present)
        set_(self, "positions", pos)
        set_(self, "velocities", vel)
        for name in ("radii", "v_pref"):
            arr = _frozen_array(getattr(self, name), name, (n_agents,))
            if name == "radii":
                _require_finite(arr, name)
            elif np.isinf(arr).any():  # v_pref: NaN means unknown, inf is an error
                _require_finite(arr[~np.isnan(arr)], name)
            if (arr < 0.0).any():
                raise ValueError(f"Trajectory.{name}: must be >= 0, got {arr.tolist()}")
            set_(self, name, arr)
        goals = _frozen_array(self.goals, "goals", (n_agents, 2))
        _require_finite(goals, "goals")
        set_(self, "goals", goals)
        roles = tuple(str(r) for r in np.asarray(self.roles, dtype=object).reshape(-1))
        if len(roles) != n_agents:
            raise ValueError(f"Trajectory.roles: expected {n_agents} roles, got {len(roles)}")
        if roles[0] != "robot" or any(r != "human" for r in roles[1:]):
            raise ValueError(
                f"Trajectory.roles: agent 0 must be 'robot' and the others 'human', got {list(roles)}"
            )
        set_(self, "roles", roles)
        if self.outcome not in OUTCOMES:
            raise ValueError(f"Trajectory.outcome: must be one of {OUTCOMES}, got {self.outcome!r}")
        if self.min_clearance is not None:
            mc = _frozen_array(self.min_clearance, "min_clearance", (n_samples - 1,))
            if np.isnan(mc).any():
                raise ValueError("Trajectory.min_clearance: contains NaN")
            set_(self, "min_clearance", mc)
        if self.continuation is not None:
            if present is not None:
                raise ValueError("Trajectory.continuation: not supported with absent agents (present mask)")
            cont = _frozen_array(self.continuation, "continuation", (None, n_agents, 2))
            _require_finite(cont, "continuation")
            set_(self, "continuation", cont)
        if self.human_overlaps is not None:
            ho = int(self.human_overlaps)
            if ho != self.human_overlaps or ho < 0:
                raise ValueError(
                    f"Trajectory.human_overlaps: must be a non-negative int, got {self.human_overlaps!r}"
                )
            set_(self, "human_overlaps", ho)
        if self.arrival_times is not None:
            arr = _frozen_array(self.arrival_times, "arrival_times", (n_agents,))
            if np.any(np.isinf(arr)) or np.any(arr < 0.0):
                raise ValueError(f"Trajectory.arrival_times: must be >= 0 or NaN (unknown), "
                                 f"got {arr.tolist()}")
            set_(self, "arrival_times", arr)
        if self.static_map is not None:
            smap = self.static_map
            if not isinstance(smap, StaticMap):
                raise ValueError(
                    f"Trajectory.static_map: must be a StaticMap or None, got {type(smap).__name__}"
                )
            set_(self, "static_map", smap if smap else None)
        if not isinstance(self.settings, Mapping):
            raise ValueError(f"Trajectory.settings: must be a mapping, got {type(self.settings)}")
        set_(self, "settings", dict(self.settings))

    def _check_present(self, n_samples: int, n_agents: int) -> np.ndarray | None:
        if self.present is None:
            return None
        mask = np.asarray(self.present)
        if mask.shape != (n_samples, n_agents) or mask.dtype != bool:
            raise ValueError(f"Trajectory.present: expected a bool array of shape ({n_samples}, {n_agents}), "
                             f"got {mask.dtype} {mask.shape}")
        if not mask[:, 0].all():
            k = int(np.flatnonzero(~mask[:, 0])[0])
            raise ValueError(f"Trajectory.present: the robot (agent 0) must be present at every sample; "
                             f"absent at sample {k}")
        if mask.all():
            return None
        mask = mask.copy()
        mask.setflags(write=False)
        return mask

    # ------------------------------------------------------------------ derived quantities
    @property
    def presence(self) -> np.ndarray:
        """Presence mask (K+1, A) bool, all True when :attr:`present` is None."""
        if self.present is None:
            return np.ones(self.positions.shape[:2], dtype=bool)
        return self.present

    @property
    def n_steps(self) -> int:
        """Number of steps K (samples are 0..K)."""
        return self.positions.shape[0] - 1

    @property
    def n_agents(self) -> int:
        """Number of agents A = 1 + number of humans."""
        return self.positions.shape[1]

    @property
    def n_humans(self) -> int:
        """Number of humans A − 1."""
        return self.positions.shape[1] - 1

    @property
    def duration(self) -> float:
        """Episode duration T = K·dt [s]."""
        return self.n_steps * self.dt

    @property
    def times(self) -> np.ndarray:
        """Sample times t_k = k·dt [s], shape (K+1,)."""
        return np.arange(self.n_steps + 1) * self.dt

    def executed_velocities(self) -> np.ndarray:
        """Velocities executed between samples, v_k = (p_k − p_{k−1})/dt for k = 1..K.

        Returns:
            [m/s], shape (K, A, 2); row k−1 holds v_k.
        """
        return self.derived("executed_velocities", lambda: np.diff(self.positions, axis=0) / self.dt)

    def derived(self, name: str, compute: Callable[[], Any]) -> Any:
        """``compute()`` once per trajectory, then the stored result (read-only when an array).

        Several metrics (and several settings of one) start from the same derived arrays; a
        trajectory never changes after construction, so they are computed once.
        """
        cache = self.__dict__.setdefault("_derived", {})
        if name not in cache:
            value = compute()
            if isinstance(value, np.ndarray):
                value.setflags(write=False)
            cache[name] = value
        return cache[name]

    @classmethod
    def from_positions(
        cls,
        positions: np.ndarray,
        dt: float,
        *,
        radii: float | np.ndarray | None = None,
        v_pref: float | np.ndarray | None = None,
        goals: np.ndarray | None = None,
        outcome: str = "unknown",
        present: np.ndarray | None = None,
        **kwargs: Any,
    ) -> Trajectory:
        """Build a Trajectory from positions alone, deriving velocities by finite differences.

        Velocity k (k ≥ 1) is (p_k − p_{k−1})/dt; an agent's first present sample copies the next
        velocity (zero when it has one sample), because a log rarely records the velocity before its
        first sample. Nothing that changes a score is assumed silently:

        - ``radii`` is required (every clearance-based metric depends on it);
        - ``v_pref`` defaults to NaN (unknown), which no metric uses;
        - ``goals`` defaults to each agent's last present position, with an
          :class:`AssumedValueWarning` (M_III's arrivals then happen at the end by construction);
        - ``outcome`` defaults to ``"unknown"``: basic rates are NaN and
          :func:`socialnav.metrics.score_episode` warns that social metrics are NaN unless
          ``require_success=False``.

        Args:
            positions: [m], shape (K+1, A, 2), agent 0 the robot; NaN allowed where ``present`` is False.
            dt: Step [s].
            radii: [m], scalar or shape (A,). Required.
            v_pref: [m/s], scalar or shape (A,); default NaN (unknown).
            goals: [m], shape (A, 2); default each agent's last present position (with a warning).
            outcome: One of ``OUTCOMES``.
            present: Presence mask (K+1, A) bool; default every agent present at every sample.
            **kwargs: Other Trajectory fields (min_clearance, continuation, settings, ...).

        Returns:
            The validated Trajectory.

        Raises:
            ValueError: ``radii`` missing, or a field fails validation.
        """
        pos = np.array(positions, dtype=np.float64)
        if pos.ndim != 3 or pos.shape[-1] != 2:
            raise ValueError(f"Trajectory.positions: expected shape (K+1, A, 2), got {pos.shape}")
        if radii is None:
            raise ValueError("Trajectory.from_positions: radii is required (agent body radii [m], scalar "
                             "or one per agent); clearance-based metrics depend on it")
        n_agents = pos.shape[1]
        mask = np.ones(pos.shape[:2], dtype=bool) if present is None else np.asarray(present, dtype=bool)
        if mask.shape != pos.shape[:2]:
            raise ValueError(f"Trajectory.present: expected shape {pos.shape[:2]}, got {mask.shape}")
        vel = derive_velocities(pos, mask, float(dt))
        if goals is None:
            goals = last_present_positions(pos, mask)
            warnings.warn("Trajectory.from_positions: goals not given; assumed each agent's last position",
                          AssumedValueWarning, stacklevel=2)
        v_pref = np.nan if v_pref is None else v_pref
        per_agent = {}
        for name, value in (("radii", radii), ("v_pref", v_pref)):
            arr = np.asarray(value, dtype=np.float64)
            if arr.ndim > 1 or (arr.ndim == 1 and arr.shape[0] != n_agents):
                raise ValueError(f"Trajectory.from_positions: {name} must be a scalar or one value per agent "
                                 f"({n_agents}), got shape {arr.shape}")
            per_agent[name] = np.broadcast_to(arr, (n_agents,))
        return cls(
            dt=dt,
            positions=pos,
            velocities=vel,
            radii=per_agent["radii"],
            v_pref=per_agent["v_pref"],
            goals=goals,
            roles=("robot",) + ("human",) * (n_agents - 1),
            outcome=outcome,
            present=None if present is None else mask,
            **kwargs,
        )


def derive_velocities(positions: np.ndarray, present: np.ndarray, dt: float) -> np.ndarray:
    """Velocities (K+1, A, 2) from positions by backward differences, NaN where absent.

    v_k = (p_k − p_{k−1})/dt where both samples are present; an agent's first present sample after
    an absence (or sample 0) copies the next velocity if that exists, else 0.
    """
    pos = np.where(present[..., None], positions, np.nan)
    vel = np.full_like(pos, np.nan)
    if pos.shape[0] > 1:
        vel[1:] = np.diff(pos, axis=0) / dt
    starts = present & ~np.concatenate([np.zeros((1, pos.shape[1]), bool), present[:-1]], axis=0)
    k, a = np.nonzero(starts)
    nxt = np.minimum(k + 1, pos.shape[0] - 1)
    ok = (k + 1 < pos.shape[0]) & present[nxt, a]
    vel[k, a] = np.where(ok[:, None], vel[nxt, a], 0.0)
    return np.where(present[..., None], vel, np.nan)


def last_present_positions(positions: np.ndarray, present: np.ndarray) -> np.ndarray:
    """Each agent's position at its last present sample, shape (A, 2) (NaN for never-present agents)."""
    out = np.full((positions.shape[1], 2), np.nan)
    for a in range(positions.shape[1]):
        ks = np.flatnonzero(present[:, a])
        if ks.size:
            out[a] = positions[ks[-1], a]
    return out


def write_trajectories(path: Any, trajs: Any) -> None:
    """Write trajectories to ``path`` (``.parquet`` or ``.csv``) atomically; see trajectory_io."""
    from socialnav.trajectory_io import write_trajectories as _write

    _write(path, trajs)


def read_trajectories(
    path: Any, *, resample: bool = False, dt: float | None = None, episodes: list[Any] | None = None,
    rows: tuple[int, int] | None = None,
) -> list[Trajectory]:
    """Read trajectories from ``path`` (``.parquet`` or ``.csv``); see trajectory_io."""
    from socialnav.trajectory_io import read_trajectories as _read

    return _read(path, resample=resample, dt=dt, episodes=episodes, rows=rows)
