"""Scenes: every agent of one recording on one time grid, with a presence mask.

A :class:`Scene` is what the importers produce before anyone is chosen as the robot. Tracks are put on
the grid t_0 + k·dt by :func:`scene_from_tracks`:

- On a regular clock (every sample of every agent on one grid, within 1e-6·dt, and every agent logged
  at that step) samples are used as they are; an agent missing at a grid time is *absent* there,
  unless ``max_gap`` is given: missing samples in gaps up to it are then interpolated.
- Otherwise (irregular clock, agents logged at different rates or times, or a requested ``dt`` the
  data are not on) every agent is resampled by **linear interpolation** of its positions (and
  velocities, when given) onto the grid. The grid passes through the logged robot's samples (its first
  one, and with the default step, fitted to a whole number of steps, its last one), else it starts at
  the scene's first timestamp; it covers the whole scene. A grid time is present for an agent when it
  lies between two of its consecutive samples at most ``max_gap`` apart (default: twice the agent's
  own median step) or on a sample; outside its track, or inside a longer gap, the agent is absent.
  Nothing is extrapolated.

:meth:`Scene.trajectory` then makes a :class:`~socialnav.trajectory.Trajectory` with one agent as the
robot: a logged robot (:meth:`Scene.robot_trajectory`) or any pedestrian scored as if it were the robot
("human as robot", :meth:`Scene.ego_trajectory`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from socialnav.trajectory import (
    AssumedValueWarning,
    Trajectory,
    TrajectoryFormatError,
    derive_velocities,
    last_present_positions,
)
from socialnav.trajectory_io.resample import step_fitted_to
from socialnav.trajectory_io.schema import MAX_RESAMPLED_STEPS

__all__ = ["DT_RTOL", "Scene", "SceneError", "id_matches", "scene_from_tracks"]

DT_RTOL = 1e-6
"""Relative tolerance on sample times: float noise in logged clocks is far below it, real jitter above."""


class SceneError(TrajectoryFormatError):
    """An agent cannot be scored as the robot (too short, or absent inside its own track)."""


@dataclass(frozen=True, eq=False)
class Scene:
    """All agents of one recording on the grid ``t0 + k·dt``.

    Attributes:
        name: Scene key (episode key or file stem).
        dt: Step [s].
        t0: Time of sample 0 [s, clock of the file].
        ids: Agent ids as in the file, shape (A,).
        positions: [m], (K+1, A, 2), NaN where absent.
        present: (K+1, A) bool.
        velocities: [m/s], (K+1, A, 2) from the file, or None (derived from positions).
        radii: [m], (A,).
        v_pref: [m/s], (A,), NaN where unknown.
        goals: [m], (A, 2), NaN where unknown.
        robot: Index (not id) of the logged robot, or None (pedestrian data).
        outcome: The logged robot's outcome (``unknown`` when not logged).
        rows: File row (0-based) of each agent's first sample, (A,), for error messages.
        source: File the scene came from.
        row_word: How ``rows`` are named in messages ("row" for tables, "line" for text files).
        resampled: Whether the tracks were interpolated onto the grid.
        settings: Extra settings copied into every trajectory.
    """

    name: str
    dt: float
    t0: float
    ids: np.ndarray
    positions: np.ndarray
    present: np.ndarray
    velocities: np.ndarray | None
    radii: np.ndarray
    v_pref: np.ndarray
    goals: np.ndarray
    robot: int | None = None
    outcome: str = "unknown"
    rows: np.ndarray | None = None
    source: str = ""
    resampled: bool = False
    settings: dict[str, Any] = field(default_factory=dict)
    row_word: str = "row"

    @property
    def n_agents(self) -> int:
        """The number of agents A in the scene."""
        return self.positions.shape[1]

    def index_of(self, agent_id: Any) -> int:
        """Index of the agent with id ``agent_id``; KeyError naming the scene's ids otherwise."""
        matches = np.flatnonzero(id_matches(self.ids, agent_id))
        if matches.size == 0:
            shown = ", ".join(str(i) for i in self.ids[:20]) + (" ..." if len(self.ids) > 20 else "")
            raise KeyError(f"{self.source}: scene {self.name!r} has no agent with id {agent_id!r} "
                           f"(ids: {shown})")
        return int(matches[0])

    @classmethod
    def from_trajectory(cls, traj: Trajectory, source: str = "") -> Scene:
        """The scene of a Trajectory read from the long format (its robot stays the logged robot)."""
        ids = np.asarray(traj.settings.get("agent_ids", list(range(traj.n_agents))))
        return cls(
            name=str(traj.settings.get("episode", "")), dt=traj.dt, t0=float(traj.settings.get("t0", 0.0)),
            ids=ids, positions=np.array(traj.positions), present=np.array(traj.presence),
            velocities=np.array(traj.velocities), radii=np.array(traj.radii), v_pref=np.array(traj.v_pref),
            goals=np.array(traj.goals), robot=0, outcome=traj.outcome, source=source,
            resampled=bool(traj.settings.get("resampled", False)),
            settings={k: v for k, v in traj.settings.items() if k not in ("agent_ids", "t0", "episode")},
        )

    # ------------------------------------------------------------------ trajectories
    def robot_trajectory(self) -> Trajectory:
        """The logged robot against every other agent, over the robot's track."""
        if self.robot is None:
            raise SceneError(f"{self.source}: scene {self.name!r} has no robot; score pedestrians with "
                             "ego=ID or ego='all' (CLI: --ego)")
        return self.trajectory(self.robot, human_as_robot=False)

    def ego_trajectory(self, agent_id: Any) -> Trajectory:
        """Agent ``agent_id`` scored as the robot ("human as robot") against every other agent."""
        return self.trajectory(self.index_of(agent_id), human_as_robot=True)

    def trajectory(self, ego: int, *, human_as_robot: bool) -> Trajectory:
        """Agent index ``ego`` as the robot, over its own track, against everyone else present.

        Human as robot: start and goal are the ego's first and last observed positions, the outcome is
        ``success`` (the person got where they went), and every other agent's arrival time for M_III
        is its observed exit from the scene (``arrival_times``), even after the ego's track ends.
        A logged robot keeps its logged goal (else its last position, with a warning) and outcome.

        Raises:
            SceneError: The ego has fewer than two samples or is absent inside its track.
        """
        ks = np.flatnonzero(self.present[:, ego])
        label = f"{self.source}: scene {self.name!r}, agent {self.ids[ego]}"
        row = "" if self.rows is None else f" (first sample at {self.row_word} {int(self.rows[ego]) + 1})"
        if ks.size < 2:
            raise SceneError(f"{label}{row}: has {ks.size} sample(s); at least 2 are needed to score it "
                             "as the robot")
        k0, k1 = int(ks[0]), int(ks[-1])
        if ks.size != k1 - k0 + 1:
            gap = int(np.flatnonzero(~self.present[k0 : k1 + 1, ego])[0]) + k0
            at = clock(self.t0 + gap * self.dt)
            raise SceneError(f"{label}{row}: absent at t = {at} s inside its track "
                             "(a gap longer than --max-gap, default twice its median step); the robot must "
                             "be present at every sample: pass --max-gap S to bridge gaps of up to S seconds "
                             "by interpolation")
        window = slice(k0, k1 + 1)
        others = [a for a in range(self.n_agents) if a != ego and self.present[window, a].any()]
        order = [ego] + others
        pos = self.positions[window][:, order]
        present = self.present[window][:, order]
        vel = (self.velocities[window][:, order] if self.velocities is not None
               else derive_velocities(pos, present, self.dt))
        vel = np.where(present[..., None], np.nan_to_num(vel), np.nan)
        ends = last_present_positions(self.positions, self.present)[order]
        goals = self.goals[order].copy()
        assumed = []
        if human_as_robot:
            goals[0] = pos[-1, 0]
        elif not np.all(np.isfinite(goals[0])):
            assumed.append("the robot's goal (its last position)")
        unknown_goal = ~np.all(np.isfinite(goals), axis=1)
        if unknown_goal[1:].any() and not human_as_robot:
            assumed.append("the other agents' goals (their last observed positions)")
        goals[unknown_goal] = ends[unknown_goal]
        if assumed:  # the goals are missing, not the agent: said so first
            warnings.warn(f"{label}: no goals in the data; assumed " + " and ".join(assumed),
                          AssumedValueWarning,
                          stacklevel=2)
        arrival = None
        last_k = np.array([np.flatnonzero(self.present[:, a])[-1] for a in order], dtype=float)
        if human_as_robot:
            arrival = (last_k - k0) * self.dt  # observed exit, seconds after the ego's start
            arrival[0] = np.nan  # the ego's own time is its track
        elif (unknown_goal & (last_k > k1)).any():
            # a person still in view after the robot's last sample, its goal assumed where it was last seen:
            # its observed exit is its arrival (the window, cut at the robot's end, never shows it there)
            arrival = np.where(unknown_goal & (last_k > k1), (last_k - k0) * self.dt, np.nan)
            arrival[0] = np.nan
        settings = {
            **self.settings, "scene": self.name, "source": self.source, "t0": self.t0 + k0 * self.dt,
            "agent_ids": [_plain(self.ids[a]) for a in order], "ego": _plain(self.ids[ego]),
            "mode": "human_as_robot" if human_as_robot else "robot",
        }
        if self.resampled:
            settings["resampled"] = True
        return Trajectory(
            dt=self.dt, positions=np.nan_to_num(pos), velocities=np.nan_to_num(vel),
            radii=self.radii[order], v_pref=self.v_pref[order], goals=goals,
            roles=("robot",) + ("human",) * (len(order) - 1),
            outcome="success" if human_as_robot else self.outcome,
            present=present, arrival_times=arrival, settings=settings,
        )


def id_matches(ids: np.ndarray, agent_id: Any) -> np.ndarray:
    """Which of ``ids`` name ``agent_id``: equal as text, or as numbers (``104.0`` names agent 104)."""
    out = ids.astype(str) == str(agent_id)
    if not out.any():
        try:
            number = float(str(agent_id))
        except ValueError:
            return out
        numeric = np.array([_as_float(i) for i in ids], dtype=float)
        out = numeric == number
    return out


def _as_float(value: Any) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return np.nan


def _plain(value: Any) -> Any:
    return value.item() if isinstance(value, np.generic) else value


# ------------------------------------------------------------------------------------ grid building
def clock(t: float) -> str:
    """A time [s] for a message: ``%g``, with the fractional digits an epoch stamp needs (1.7e9 s)."""
    t = float(t)
    return f"{t:.6f}".rstrip("0").rstrip(".") if abs(t) >= 1e5 else f"{t:g}"


def scene_from_tracks(
    *,
    name: str,
    source: str,
    t: np.ndarray,
    agent: np.ndarray,
    xy: np.ndarray,
    rows: np.ndarray,
    velocity: np.ndarray | None = None,
    dt: float | None = None,
    max_gap: float | None = None,
    anchor: Any = None,
    time_column: str = "t",
    fail: Any,
    time_origin: float = 0.0,
) -> tuple[np.ndarray, dict[str, Any]]:
    """Put the samples of one scene on a grid (see the module docstring).

    Args:
        name: The scene's name, for messages.
        source: The file it came from, for messages.
        t: (n,) sample times [s].
        agent: (n,) agent ids.
        xy: (n, 2) positions [m].
        rows: (n,) file rows of the samples, for messages.
        velocity: (n, 2) velocities [m/s], or None (the grid's ``velocities`` is then None).
        dt: Grid step [s]; default the median step between consecutive samples of one agent, rounded
            to 12 significant digits (recovers a dt written as text).
        max_gap: Longest gap [s] bridged by interpolation; default twice each agent's own median step
            when resampling, and no bridging on a regular clock.
        anchor: Id of the agent whose track the resampled grid follows (the logged robot): the grid
            passes through its first sample and, with the default ``dt``, its step is adjusted so that
            the grid also passes through its last one.
        time_column: The name of the time column in the file, for messages.
        time_origin: What ``t`` is counted from [s, the file's clock], for messages.
        fail: ``fail(column, row, message) -> Exception`` naming the file.

    Returns:
        (ids, grid) where grid has ``dt``, ``t0``, ``positions``, ``present``, ``velocities``,
        ``first_rows`` (row of each agent's first sample) and ``resampled``.
    """
    order = np.lexsort((np.arange(len(t)), agent))  # by agent, then file order
    ids, starts = np.unique(agent[order], return_index=True)
    bounds = np.append(starts, len(order))
    steps_all = []
    anchor_steps = None  # the logged robot's own steps: its clock sets the grid, whoever else is in view
    for i in range(len(ids)):
        sel = order[bounds[i] : bounds[i + 1]]
        ts = t[sel]
        by_time = np.argsort(ts, kind="stable")
        same = np.flatnonzero(np.diff(ts[by_time]) == 0)
        if same.size:  # reported before ordering problems: the clearer diagnosis
            a, b = sorted((int(rows[sel[by_time[same[0]]]]), int(rows[sel[by_time[same[0] + 1]]])))
            at = clock(time_origin + ts[by_time[same[0]]])
            raise fail(time_column, b, f"duplicated sample: agent {ids[i]} at t = {at} s also at "
                       f"{getattr(fail, 'unit', 'row')} {a + 1}")
        d = np.diff(ts)
        if np.any(d <= 0):
            j = int(np.flatnonzero(d <= 0)[0])
            raise fail(time_column, int(rows[sel[j + 1]]), f"time goes backwards for agent {ids[i]}: "
                       f"{clock(time_origin + ts[j])} -> {clock(time_origin + ts[j + 1])} s (rows must be in "
                       "time order per agent)")
        steps_all.append(d)
        if anchor is not None and str(ids[i]) == str(anchor) and d.size:
            anchor_steps = d
    if anchor_steps is not None:
        steps = anchor_steps
    else:
        steps = np.concatenate(steps_all) if steps_all else np.zeros(0)
    requested = dt
    if dt is None:
        if steps.size == 0:
            raise fail(time_column, int(rows[0]), f"scene {name!r}: every agent has one sample; cannot tell "
                       "the time step (pass dt)")
        dt = float(f"{np.median(steps):.12g}")
    if not np.isfinite(dt) or dt <= 0:
        raise TrajectoryFormatError(f"{source}: dt must be > 0, got {dt!r}")
    if max_gap is not None and not (np.isfinite(max_gap) and max_gap > 0):
        raise ValueError(f"max_gap must be a finite number of seconds > 0, got {max_gap!r}")
    t0, t1 = float(t.min()), float(t.max())
    k_float = (t - t0) / dt
    k_int = np.rint(k_float)
    on_grid = bool(np.all(np.abs(k_float - k_int) <= DT_RTOL * max(1.0, float(k_int.max(initial=0)))))
    # a requested dt other than the data's own step means resampling, not a sparse grid; so does an agent
    # logged at another rate (a 10 Hz people tracker beside 50 Hz odometry is interpolated, not absent 4
    # samples in 5)
    native = all(abs(float(np.median(d)) - dt) <= DT_RTOL * dt for d in steps_all if d.size)
    regular = on_grid and native
    a_index = np.searchsorted(ids, agent)
    if regular:
        n = int(np.rint((t1 - t0) / dt)) + 1
        grid_t0 = t0
    else:
        grid_t0, dt, n = _resampling_grid(name, source, t, agent, ids, anchor, requested, dt, t0, t1)
    if n > MAX_RESAMPLED_STEPS:
        raise TrajectoryFormatError(
            f"{source}: scene {name!r}: a {dt:g} s grid over its {t1 - t0:g} s has {n} samples (more than "
            f"{MAX_RESAMPLED_STEPS}); is the time step (--dt) or the time unit (--time-unit) wrong?")
    pos = np.full((n, len(ids), 2), np.nan)
    present = np.zeros((n, len(ids)), dtype=bool)
    vel = None if velocity is None else np.full((n, len(ids), 2), np.nan)
    if regular:
        k = k_int.astype(np.int64)
        pos[k, a_index] = xy
        present[k, a_index] = True
        if vel is not None:
            vel[k, a_index] = velocity
        if max_gap is not None:
            _fill_gaps(name, source, pos, present, vel, dt, max_gap)
    else:
        grid = grid_t0 + dt * np.arange(n)
        for i in range(len(ids)):
            sel = order[bounds[i] : bounds[i + 1]]
            ts = t[sel]
            # each agent's own clock: a slow tracker beside a fast odometry keeps its people
            gap = (2.0 * float(np.median(steps_all[i])) if steps_all[i].size else 0.0) if max_gap is None \
                else float(max_gap)
            j = np.searchsorted(ts, grid, side="right") - 1  # sample at or before each grid time
            on = (j >= 0) & (j < len(ts))
            nxt = np.minimum(j + 1, len(ts) - 1)
            exact = on & (np.abs(ts[np.clip(j, 0, None)] - grid) <= DT_RTOL * dt)
            exact |= (j + 1 < len(ts)) & (np.abs(ts[nxt] - grid) <= DT_RTOL * dt)  # just before a sample
            inside = on & (j + 1 < len(ts)) & (ts[nxt] - ts[np.clip(j, 0, None)] <= gap + DT_RTOL * dt)
            ok = exact | inside
            present[:, i] = ok
            for d in (0, 1):
                pos[ok, i, d] = np.interp(grid[ok], ts, xy[sel, d])
                if vel is not None:
                    vel[ok, i, d] = np.interp(grid[ok], ts, velocity[sel, d])
    first_rows = np.array([rows[order[b]] for b in bounds[:-1]], dtype=np.int64)
    return ids, {"dt": dt, "t0": grid_t0, "positions": pos, "present": present, "velocities": vel,
                 "first_rows": first_rows, "resampled": not regular}


def _resampling_grid(name: str, source: str, t: np.ndarray, agent: np.ndarray, ids: np.ndarray, anchor: Any,
                     requested: float | None, dt: float, t0: float, t1: float) -> tuple[float, float, int]:
    """(first grid time, step, samples) of an irregular scene's grid.

    Without an anchor the grid starts at the scene's first time stamp. With one (the logged robot) it
    passes through the anchor's first sample and, when the step is the data's median rather than a
    requested one, the step is adjusted (by less than half a step over the track) so that it also passes
    through the anchor's last sample: the robot's whole run is scored, not its run cut to whole median
    steps (a jittered 0.48-0.52 s clock over 2 s would otherwise lose 0.08 s of navigation time).
    """
    match = np.flatnonzero(ids.astype(str) == str(anchor)) if anchor is not None else np.zeros(0, dtype=int)
    if match.size == 0:
        return t0, dt, int(np.floor((t1 - t0) / dt + 1e-9)) + 1
    mine = t[agent == ids[match[0]]]
    a0, a1 = float(mine.min()), float(mine.max())
    span = a1 - a0
    if requested is None:
        dt = step_fitted_to(span, dt)
    elif span > 0:
        lost = span - np.floor(span / dt + 1e-9) * dt
        if lost > DT_RTOL * dt:
            warnings.warn(f"{source}: scene {name!r}: the {dt:g} s grid ends {lost:.3g} s before the last "
                          f"sample of agent {ids[match[0]]} (the requested step does not divide its "
                          f"{span:g} s track; leave --dt out to fit the step to it)", AssumedValueWarning,
                          stacklevel=4)
    before = int(np.floor((a0 - t0) / dt + 1e-9))
    after = int(np.floor((t1 - a0) / dt + 1e-9))
    return a0 - before * dt, dt, before + after + 1


def _fill_gaps(name: str, source: str, pos: np.ndarray, present: np.ndarray, vel: np.ndarray | None,
               dt: float, max_gap: float) -> None:
    """Interpolate the missing samples of regular-clock tracks in gaps of at most ``max_gap``, in place."""
    filled = 0
    for i in range(present.shape[1]):
        ks = np.flatnonzero(present[:, i])
        for a, b in zip(ks[:-1], ks[1:], strict=True):
            if b - a < 2 or (b - a) * dt > max_gap + DT_RTOL * dt:
                continue
            w = (np.arange(a + 1, b) - a) / (b - a)
            pos[a + 1 : b, i] = pos[a, i] + w[:, None] * (pos[b, i] - pos[a, i])
            if vel is not None:
                vel[a + 1 : b, i] = vel[a, i] + w[:, None] * (vel[b, i] - vel[a, i])
            present[a + 1 : b, i] = True
            filled += b - a - 1
    if filled:
        warnings.warn(f"{source}: scene {name!r}: {filled} missing sample(s) in gaps of at most --max-gap "
                      f"{max_gap:g} s linearly interpolated", AssumedValueWarning, stacklevel=4)
