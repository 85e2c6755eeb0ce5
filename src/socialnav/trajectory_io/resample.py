"""Time grids of an episode being read.

Checking that agents share one regular grid, placing agents that enter and leave on the robot's
grid, and resampling by linear interpolation onto a fixed step. Each agent is given as a dict of its
rows (``rows``), times (``t``, s), continuation flags (``cont``), positions (``pos``, (K, 2) m) and
velocities (``vel``, (K, 2) m/s or None when the file has none).
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from socialnav.trajectory import AssumedValueWarning, TrajectoryFormatError
from socialnav.trajectory_io.schema import DT_RTOL, MAX_RESAMPLED_STEPS, step_from_span, time_tolerance
from socialnav.trajectory_io.table import TrajectoryTable


def check_grid(
    tab: TrajectoryTable, per_agent: list[dict[str, Any]], dt_arg: float | None, key: Any
) -> tuple[bool, float]:
    """Whether all agents share one regular main time grid, and the step to use.

    Args:
        tab: The file's table (for errors).
        per_agent: The episode's agents, robot first.
        dt_arg: The step the caller passed [s], or None to take the robot's.
        key: The episode's key (for errors).

    Returns:
        ``(regular, dt)``, dt in s.

    Raises:
        TrajectoryFormatError: ``dt_arg`` is not positive, or a one-sample episode without it.
    """
    robot_t = per_agent[0]["t"][~per_agent[0]["cont"]]
    steps = np.diff(robot_t)
    if dt_arg is not None:
        dt = float(dt_arg)
        if not np.isfinite(dt) or dt <= 0:
            raise TrajectoryFormatError(f"{tab.path}: dt argument must be > 0, got {dt_arg!r}")
    elif steps.size:
        dt = step_from_span(robot_t[-1] - robot_t[0], steps.size, robot_t)
    else:
        raise tab.fail("t", int(per_agent[0]["rows"][0]), f"episode {key!r} has one sample: pass dt=")
    tol = time_tolerance(dt, robot_t)
    regular = bool(np.all(np.abs(steps - dt) <= tol))
    for p in per_agent[1:]:
        t = p["t"][~p["cont"]]
        regular &= t.shape == robot_t.shape and bool(np.all(np.abs(t - robot_t) <= tol))
    return regular, dt


def masked_grid(
    per_agent: list[dict[str, Any]], dt: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Agents entering or leaving: every sample on the robot's regular grid, some agents absent.

    An absent agent has no row at that sample.

    Args:
        per_agent: The episode's agents, robot first.
        dt: The step [s].

    Returns:
        ``(positions (K, A, 2), velocities (K, A, 2), present (K, A))``, or None when that is not
        the case.
    """
    if any(np.any(p["cont"]) for p in per_agent):
        return None  # continuation samples need every agent at every sample
    robot_t = per_agent[0]["t"]
    tol = time_tolerance(dt, robot_t)
    if robot_t.size < 2 or not np.all(np.abs(np.diff(robot_t) - dt) <= tol):
        return None
    n = robot_t.size
    pos = np.full((n, len(per_agent), 2), np.nan)
    present = np.zeros((n, len(per_agent)), dtype=bool)
    given = per_agent[0]["vel"] is not None
    vel = np.full_like(pos, np.nan)
    for a, p in enumerate(per_agent):
        k = (p["t"] - robot_t[0]) / dt
        ki = np.rint(k)
        off_grid = np.abs(k - ki) > np.maximum(DT_RTOL * np.abs(k), time_tolerance(dt, p["t"]) / dt)
        if np.any(off_grid) or ki.min() < 0 or ki.max() > n - 1:
            return None
        ki = ki.astype(np.int64)
        pos[ki, a], present[ki, a] = p["pos"], True
        if given:
            vel[ki, a] = p["vel"]
    if not given:
        from socialnav.trajectory import derive_velocities

        vel = derive_velocities(pos, present, dt)
    return np.nan_to_num(pos), np.nan_to_num(vel), present


def grid_error(
    tab: TrajectoryTable, per_agent: list[dict[str, Any]], dt: float, key: Any
) -> TrajectoryFormatError:
    """Describe the first sample that breaks a shared regular grid."""
    robot = per_agent[0]
    robot_t = robot["t"][~robot["cont"]]
    tol = time_tolerance(dt, robot_t)
    hint = " (resample it: --resample on the command line, resample=True in Python)"
    steps = np.diff(robot_t)
    ref = float(np.median(steps)) if steps.size else dt  # the typical step, to point at the odd one
    if steps.size and np.all(np.abs(steps - ref) <= tol) and abs(ref - dt) > tol:
        return tab.fail("t", int(robot["rows"][1]), f"episode {key!r} is sampled every {ref:g} s but "
                        f"dt={dt:g} was passed{hint}")
    for i, step in enumerate(steps):
        if abs(step - ref) > tol:
            return tab.fail("t", int(robot["rows"][i + 1]), f"irregular sampling in episode {key!r}: step "
                            f"{step:g} s, typical step {ref:g} s{hint}")
    for p in per_agent[1:]:
        t = p["t"][~p["cont"]]
        n = min(len(t), len(robot_t))
        off = np.flatnonzero(np.abs(t[:n] - robot_t[:n]) > tol)
        if off.size:
            i = int(off[0])
            if t[i] < robot_t[i]:
                what = (f"agent {p['id']} has a sample at t = {t[i]:g} s where the robot (agent 0) has none "
                        f"(its next is at t = {robot_t[i]:g} s)")
            else:
                what = (f"the robot (agent 0) has a sample at t = {robot_t[i]:g} s where agent {p['id']} has "
                        f"none (its next is at t = {t[i]:g} s)")
            return tab.fail("t", int(p["rows"][i]), f"episode {key!r}: {what}{hint}")
        if len(t) != len(robot_t):
            return tab.fail("t", int(p["rows"][n - 1]), f"episode {key!r}: agent {p['id']} has {len(t)} "
                            f"samples, the robot (agent 0) {len(robot_t)}{hint}")
    return tab.fail("t", int(robot["rows"][0]), f"irregular sampling in episode {key!r}{hint}")


def grid_velocities(per_agent: list[dict[str, Any]], pos: np.ndarray, dt: float) -> np.ndarray:
    """The agents' velocities on a regular grid: as given, else finite differences of ``pos``.

    Args:
        per_agent: The episode's agents, robot first.
        pos: Positions on the grid, (K, A, 2) m.
        dt: The step [s].

    Returns:
        Velocities, (K, A, 2) m/s (the first sample's is the second's when derived).
    """
    if per_agent[0]["vel"] is not None:
        return np.stack([p["vel"][~p["cont"]] for p in per_agent], axis=1)
    vel = np.zeros_like(pos)
    if pos.shape[0] > 1:
        vel[1:] = np.diff(pos, axis=0) / dt
        vel[0] = vel[1]  # the velocity before the first logged sample is unknown
    return vel


def regular_continuation(
    tab: TrajectoryTable, per_agent: list[dict[str, Any]], t_end: float, dt: float, key: Any
) -> np.ndarray | None:
    """The continuation samples, which must continue the main grid for every agent.

    Args:
        tab: The file's table (for errors).
        per_agent: The episode's agents, robot first.
        t_end: The last main sample's time [s].
        dt: The step [s].
        key: The episode's key (for errors).

    Returns:
        Positions (M, A, 2) m, or None when there is no continuation.

    Raises:
        TrajectoryFormatError: An agent's continuation is off the grid or of another length.
    """
    robot = per_agent[0]
    n = int(np.sum(robot["cont"]))
    if n == 0 and not any(np.any(p["cont"]) for p in per_agent):
        return None
    expected = t_end + dt * np.arange(1, n + 1)
    for p in per_agent:
        t = p["t"][p["cont"]]
        rows = p["rows"][p["cont"]]
        if len(t) != n:
            raise tab.fail("continuation", int(rows[0] if len(rows) else p["rows"][-1]),
                           f"episode {key!r}: agent {p['id']} has {len(t)} continuation samples, the robot "
                           f"(agent 0) {n}")
        off = np.flatnonzero(np.abs(t - expected) > time_tolerance(dt, t) * np.arange(1, n + 1))
        if off.size:
            raise tab.fail("t", int(rows[off[0]]), f"continuation sample at t = {t[off[0]]:g} s, expected "
                           f"{expected[off[0]]:g} s (continuation must continue the grid)")
    return np.stack([p["pos"][p["cont"]] for p in per_agent], axis=1)


def step_fitted_to(span: float, step: float) -> float:
    """The step nearest ``step`` of which a whole number spans ``span`` (``step`` itself when ``span`` is 0).

    A resampled run then ends on its last sample: with a jittered clock (median step 0.49 s over 2 s)
    a grid of the median step would stop 0.04 s short, shortening the navigation time.

    Args:
        span: The run's duration [s].
        step: The step wanted [s], e.g. the median of the logged steps.

    Returns:
        ``span / round(span / step)`` (at least one step), differing from ``step`` by less than half a
        step over the run.
    """
    return span / max(1, round(span / step)) if span > 0 else step


#: A person's gap longer than this many of its median steps is a lost track (absent there), not bridged.
MAX_GAP_STEPS = 2.0


def resample_to_grid(
    per_agent: list[dict[str, Any]], dt: float, fit_step: bool, where: str = "resampling"
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray, np.ndarray | None, float]:
    """Linear interpolation of every agent onto t_0 + k·dt over the robot's time span.

    The robot's whole run is kept: a human whose track starts after the robot's or ends before it is
    absent outside its own track (nothing is extrapolated), instead of the grid being cut to the span
    every agent shares; inside its track it is absent in a gap longer than ``MAX_GAP_STEPS`` of its
    median steps (a tracker that lost it: not interpolated across). With ``fit_step`` (no step
    requested) the step is adjusted, by less than half a step over the run, so that the grid ends on
    the robot's last sample.

    Args:
        per_agent: The episode's agents, robot first.
        dt: The step [s]: the requested one, or the median of the robot's steps.
        fit_step: Whether ``dt`` may be adjusted to end on the robot's last sample.
        where: The file and episode, for the warning that a requested step cuts the run short.

    Returns:
        ``(positions, velocities, continuation or None, grid times, present or None, dt)``; ``present``
        is None when every agent covers the whole grid.

    Raises:
        TrajectoryFormatError: The grid would have more than ``MAX_RESAMPLED_STEPS`` samples.
    """
    main = [(p["t"][~p["cont"]], p["pos"][~p["cont"]]) for p in per_agent]
    t0, t1 = float(main[0][0][0]), float(main[0][0][-1])
    span = t1 - t0
    if fit_step:
        dt = step_fitted_to(span, dt)
    k = int(np.floor(span / dt + 1e-9))
    lost = span - k * dt
    if lost > time_tolerance(dt, main[0][0]):
        warnings.warn(f"{where}: the {dt:g} s grid ends {lost:.3g} s before the robot's last sample (the "
                      f"requested step does not divide its {span:g} s run; leave dt out to fit the step to "
                      "it)", AssumedValueWarning, stacklevel=2)
    if k >= MAX_RESAMPLED_STEPS:
        raise TrajectoryFormatError(f"resampling {span:.6g} s at dt {dt:.6g} s makes {k + 1} samples per "
                                    f"agent, more than the {MAX_RESAMPLED_STEPS} allowed: raise --dt")
    grid = t0 + dt * np.arange(k + 1)
    tol = time_tolerance(dt, grid)
    present = np.stack([(grid >= t[0] - tol) & (grid <= t[-1] + tol) for t, _ in main], axis=1)
    for a, (t, _) in enumerate(main[1:], start=1):  # a person the tracker lost is absent, not interpolated
        steps = np.diff(t)
        if steps.size < 2:
            continue
        longest = MAX_GAP_STEPS * float(np.median(steps))  # as a table's default --max-gap
        for i in np.flatnonzero(steps > longest + tol):
            present[(grid > t[i] + tol) & (grid < t[i + 1] - tol), a] = False
    present[:, 0] = True
    pos = np.stack([np.stack([np.interp(grid, t, x[:, d]) for d in (0, 1)], -1) for t, x in main], 1)
    if per_agent[0]["vel"] is not None:
        vel = np.stack([np.stack([np.interp(grid, p["t"][~p["cont"]], p["vel"][~p["cont"], d])
                                  for d in (0, 1)], -1) for p in per_agent], 1)
    elif present.all():
        vel = grid_velocities([{"vel": None}], pos, dt)
    else:
        from socialnav.trajectory import derive_velocities

        vel = derive_velocities(np.where(present[..., None], pos, np.nan), present, dt)
    if present.all():
        cont = None
        if all(np.any(p["cont"]) for p in per_agent):
            c_end = min(p["t"][-1] for p in per_agent)
            m = int(np.floor((c_end - grid[-1]) / dt + 1e-9))
            if m > 0:
                c_grid = grid[-1] + dt * np.arange(1, m + 1)
                cont = np.stack([np.stack([np.interp(c_grid, p["t"], p["pos"][:, d]) for d in (0, 1)], -1)
                                 for p in per_agent], 1)
        return pos, vel, cont, grid, None, dt
    # an absent agent's values are zeros under the mask, as on a masked regular grid
    pos = np.where(present[..., None], pos, 0.0)
    vel = np.where(present[..., None], np.nan_to_num(vel), 0.0)
    return pos, vel, None, grid, present, dt
