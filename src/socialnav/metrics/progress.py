"""Progress among walls: stuck agents and the humans' arrivals at their goals (docs/metrics.md).

Where walls stand between people and their goals, a crowd can jam: someone pressed against a wall, or
waiting at a door that never clears. These metrics read that from the trajectory alone (never the
simulator), so they score logs with a map as well as simulated episodes. They are declared
``map_only``: :func:`~socialnav.metrics.score.score_episode` reports them for episodes with a static map
and leaves their keys out on an open floor, where the results files of the original protocol keep
their columns byte for byte. Called directly, every function here works on any trajectory.

**Route distance.** D_a(t) is agent a's distance to its goal along the shortest free path of a disc of
its radius around the obstacles (the free-space, or geodesic, distance:
:func:`socialnav.maps.routes.route_distances`, the visibility graph of ``cpp/routes.hpp``). It is the
Euclidean distance on an open floor (no map), and where no route exists (``inf``: a centre inside a
solid polygon, a goal walled in) the Euclidean distance stands in. A wall between an agent and its
goal is why the geodesic matters: walking along the wall towards its middle shortens the straight-line
distance and lengthens the route.

**Stuck.** Agent a is stuck at sample k when it has not yet reached its goal (its centre within its
radius of the goal, |p − g| < r as the simulator's test and M_III's, at some sample up to k, or a known
arrival time ≤ t_k) and its route distance shrank by less than :data:`STUCK_PROGRESS_M` over the
:data:`STUCK_WINDOW_S` ending at k: D(t_k − W) − D(t_k) < P, for t_k ≥ W. D costs a visibility test
per point, so it is evaluated every :data:`STUCK_STRIDE_S` (samples k = 0, s, 2s, ... with
s = max(1, ⌊1 s / dt⌋), spacing Δ = s·dt: 1 s at the protocols' dt = 0.25 s, dt itself when dt > 1 s),
and the window is the shortest whole number L = ⌈W/Δ⌉ of spacings that covers W (W itself whenever
dt divides 1 s). A second suffices for a 5 s window: the distance changes by at most the walking
speed times Δ between evaluated samples, so a stuck spell is found to within Δ of its start and end,
and the windows of neighbouring evaluated samples share W − Δ = 4 s of their 5. Absent samples (logs)
have no distance and are never stuck, nor the start of a window.

- ``humans_stuck``: the humans stuck at one evaluated sample at least, over the episode and its
  continuation (the humans walk on after the robot's success).
- ``robot_stuck_time`` [s]: the robot's stuck evaluated samples during its episode, each counting Δ.

**Arrival.** ``human_arrival`` is the share of the episode's humans (those present at one sample at
least) that reached their goal at some sample, episode and continuation; NaN without humans. Its
``full_time`` output is the same share on episodes whose humans had the whole time (the robot
succeeded, and the data run on after it: a continuation, or every human had arrived already), NaN on
the others: after a collision or a timeout the trajectory stops, and the humans could not arrive.
"""

from __future__ import annotations

import math

import numpy as np

from socialnav.metrics.registry import register_metric
from socialnav.trajectory import Trajectory

__all__ = [
    "STUCK_PROGRESS_M",
    "STUCK_STRIDE_S",
    "STUCK_WINDOW_S",
    "human_arrival",
    "human_arrivals",
    "humans_had_full_time",
    "humans_stuck",
    "robot_stuck_time",
    "route_distances",
    "stuck_flags",
    "stuck_spacing",
]

STUCK_WINDOW_S = 5.0
"""W [s]: the window over which an agent must make progress. A person walking at 1.0–1.3 m/s covers
5–6.5 m in 5 s: long enough that waiting for someone to pass (a second or two) is not stuck, short
enough that a jam is found while it lasts."""

STUCK_PROGRESS_M = 0.5
"""P [m]: the least shrinkage of the route distance over the window that is progress: a tenth of what a
walking person covers in W, so that a slow detour counts as progress and a shuffle on the spot does
not."""

STUCK_STRIDE_S = 1.0
"""The spacing [s] of the samples the route distance is evaluated at (every sample when dt is longer):
a fifth of the window, see the module docstring."""

_REFERENCE = ("socialnav's definition (docs/metrics.md, 'Progress among walls'): progress along the "
              "free-space (geodesic) distance to the goal, the shortest route of the visibility graph "
              "(Lozano-Pérez and Wesley, 'An algorithm for planning collision-free paths among polyhedral "
              "obstacles', Commun. ACM 22(10), 1979)")
_TIME_TOL = 1e-9  # [s] a known arrival time read against sample times


def route_distances(traj: Trajectory, agent: int, points: np.ndarray) -> np.ndarray:
    """Agent ``agent``'s route distance [m] from each point (n, 2) to its goal, shape (n,).

    The free-space distance of a disc of the agent's radius around ``traj.static_map`` (Euclidean
    without a map, and where no route exists); NaN where a point is NaN (absent). A radius of 0 (a point)
    is measured as a disc of 1 µm: the routes need a radius > 0.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    goal = traj.goals[agent]
    euclid = np.linalg.norm(pts - goal, axis=-1)
    smap = traj.static_map
    ok = np.isfinite(pts).all(axis=1)
    if smap is None or not ok.any():
        return euclid
    from socialnav.maps.routes import route_distances as free_space_distances  # imports the core

    out = np.full(pts.shape[0], np.nan)
    # copies: the core takes writable arrays, and a trajectory's are read-only
    found = free_space_distances(smap, np.array(pts[ok], order="C"), np.array(goal, dtype=np.float64),
                                 max(float(traj.radii[agent]), 1e-6))
    out[ok] = np.where(np.isfinite(found), found, euclid[ok])
    return out


def stuck_spacing(dt: float, window_s: float = STUCK_WINDOW_S) -> tuple[int, int]:
    """The stride s [samples] of the evaluated samples and the window L [strides] at step ``dt`` [s].

    s = max(1, ⌊STUCK_STRIDE_S / dt⌋) and L = ⌈window_s / (s·dt)⌉: (4, 5) at dt = 0.25 s, (10, 5) at
    0.1 s, (3, 6) at 0.3 s (a window of 5.4 s), (1, 3) at 2 s.
    """
    stride = max(1, math.floor(STUCK_STRIDE_S / dt + 1e-9))
    return stride, max(1, math.ceil(window_s / (stride * dt) - 1e-9))


def _samples(traj: Trajectory, agent: int, continuation: bool) -> np.ndarray:
    pos = traj.positions[:, agent]
    if continuation and traj.continuation is not None:
        pos = np.concatenate([pos, traj.continuation[:, agent]])
    return pos


def stuck_flags(traj: Trajectory, agent: int, *, continuation: bool = True,
                window_s: float = STUCK_WINDOW_S, progress_m: float = STUCK_PROGRESS_M
                ) -> tuple[np.ndarray, np.ndarray, float]:
    """Where agent ``agent`` is stuck, at the evaluated samples (see the module docstring).

    Args:
        traj: The episode.
        agent: The agent's index (0: the robot).
        continuation: Also search the continuation samples after the episode (the humans' walk on).
        window_s: W [s].
        progress_m: P [m].

    Returns:
        The evaluated sample indices (0, s, 2s, ...; into the episode's samples followed by the
        continuation's), a bool flag per evaluated sample, and their spacing Δ = s·dt [s].
    """
    if not (math.isfinite(window_s) and window_s > 0 and math.isfinite(progress_m) and progress_m >= 0):
        raise ValueError(f"stuck_flags: window_s must be finite and > 0, progress_m finite and >= 0, got "
                         f"{window_s}, {progress_m}")
    pos = _samples(traj, agent, continuation)
    stride, lag = stuck_spacing(traj.dt, window_s)
    spacing = stride * traj.dt
    index = np.arange(0, pos.shape[0], stride)
    flags = np.zeros(index.shape[0], dtype=bool)
    if index.shape[0] <= lag:
        return index, flags, spacing
    # reached by sample k: at that sample or before (the first arrival), or a known arrival time <= t_k
    inside = np.linalg.norm(pos - traj.goals[agent], axis=-1) < traj.radii[agent]  # NaN (absent): False
    reached = np.logical_or.accumulate(inside)[index]
    if traj.arrival_times is not None and np.isfinite(traj.arrival_times[agent]):
        reached |= index * traj.dt >= traj.arrival_times[agent] - _TIME_TOL
    d = route_distances(traj, agent, pos[index])
    with np.errstate(invalid="ignore"):
        flags[lag:] = (d[:-lag] - d[lag:] < progress_m) & ~reached[lag:]  # NaN (absent) compares False
    return index, flags, spacing


def human_arrivals(traj: Trajectory) -> tuple[int, int]:
    """(humans, humans that reached their goal) of one episode.

    Humans: those present at one sample at least (``n_humans``). Reached: the centre came within the
    human's radius of its goal (|p − g| < r) at some sample of the episode or its continuation, or the
    trajectory gives a known arrival time.
    """
    if traj.n_humans == 0:
        return 0, 0
    present = traj.presence[:, 1:].any(axis=0)
    pos = traj.positions[:, 1:]
    if traj.continuation is not None:
        pos = np.concatenate([pos, traj.continuation[:, 1:]])
    with np.errstate(invalid="ignore"):
        reached = (np.linalg.norm(pos - traj.goals[1:], axis=-1) < traj.radii[1:]).any(axis=0)
    if traj.arrival_times is not None:
        reached |= np.isfinite(traj.arrival_times[1:])
    return int(present.sum()), int((reached & present).sum())


def humans_had_full_time(traj: Trajectory) -> bool:
    """Whether the episode's humans had the whole time to arrive.

    True when the robot succeeded and the data run on after it (a continuation, as the protocol's
    visible pass records up to its cap) or every human had arrived already; False after a collision or
    a timeout (the trajectory stops there) and on a success without a continuation that some human had
    not finished.
    """
    if traj.outcome != "success":
        return False
    if traj.continuation is not None:
        return True
    humans, reached = human_arrivals(traj)
    return reached == humans


@register_metric("human_arrival", unit="1", direction="higher", outputs={"value": "1", "full_time": "1"},
                 reference=_REFERENCE, map_only=True)
def human_arrival(traj: Trajectory) -> dict[str, float]:
    """Share of the humans that reached their goal, episode and continuation; NaN without humans.

    ``value`` on every episode; ``full_time`` the same share where the humans had the whole time
    (:func:`humans_had_full_time`: the robot succeeded and the humans walked on), NaN elsewhere, so its
    mean is over those episodes. Reported only for episodes with a static map (``map_only``).
    """
    humans, reached = human_arrivals(traj)
    share = reached / humans if humans else float("nan")
    return {"value": share, "full_time": share if humans_had_full_time(traj) else float("nan")}


@register_metric("humans_stuck", unit="count", direction="lower", outputs={"value": "count"},
                 reference=_REFERENCE, map_only=True)
def humans_stuck(traj: Trajectory) -> dict[str, float]:
    """Humans stuck at least once: route distance to the goal shrank < 0.5 m in 5 s before arrival.

    Over the episode and its continuation, at samples 1 s apart (see the module docstring); reported
    only for episodes with a static map (``map_only``).
    """
    def count() -> int:
        return sum(bool(stuck_flags(traj, a)[1].any()) for a in range(1, traj.n_agents))

    return {"value": float(traj.derived("humans_stuck", count))}


@register_metric("robot_stuck_time", unit="s", direction="lower", outputs={"value": "s"},
                 reference=_REFERENCE, map_only=True)
def robot_stuck_time(traj: Trajectory) -> dict[str, float]:
    """Time [s] the robot was stuck: route distance to its goal shrank < 0.5 m in the 5 s before.

    During its episode, at samples 1 s apart, each stuck one counting that spacing (see the module
    docstring); never more than T − (L − 1)·Δ ≤ T, the episode's duration. Reported only for
    episodes with a static map (``map_only``).
    """
    _, flags, spacing = stuck_flags(traj, 0, continuation=False)
    return {"value": float(np.count_nonzero(flags)) * spacing}
