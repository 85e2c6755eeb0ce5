"""What the figures and the HTML viewer show about an episode, as plain arrays (NumPy only).

The metric overlays reuse the metric code itself (``socialnav.metrics``), so that a drawn violation
is exactly a counted one:

- ``personal_space`` (M_I): a ring of radius r_robot + ε around the robot, red at samples that M_I
  flags (clearance below ε).
- ``velocity_rectangles`` (M_II): every agent's velocity rectangle (width 2r, length τ·|v|), red at
  samples where the robot's intersects a human's.
- ``side_preference`` (M_VI, single-human episodes): the sample where the label is read, the
  robot-centred frame (travel direction +y) and the label.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from socialnav.trajectory import Trajectory

OVERLAYS = ("personal_space", "velocity_rectangles", "side_preference", "lidar")
OVERLAY_ALIASES = {"m1": "personal_space", "m2": "velocity_rectangles", "m6": "side_preference"}


def parse_overlays(names: list[str] | tuple[str, ...] | None) -> tuple[str, ...]:
    """Normalises overlay names (``all``, aliases m1/m2/m6); unknown names raise listing the valid ones."""
    out: list[str] = []
    for name in names or ():
        for part in str(name).split(","):
            part = part.strip()
            if not part:
                continue
            if part == "all":
                out.extend(OVERLAYS)
                continue
            part = OVERLAY_ALIASES.get(part, part)
            if part not in OVERLAYS:
                raise ValueError(
                    f"unknown overlay {part!r}; valid: {', '.join(OVERLAYS)}, all "
                    f"(aliases {', '.join(OVERLAY_ALIASES)})"
                )
            out.append(part)
    return tuple(dict.fromkeys(out))


@dataclass(frozen=True)
class EpisodeView:
    """An episode as drawn: every sample (continuation included) and per-sample flags.

    positions: (S, A, 2) main samples then continuation samples; ``n_main`` = K + 1.
    velocities: (S, A, 2) executed velocities (p_k − p_{k−1})/dt, sample 0 the first step's.
    collision: (S,) the robot overlaps a human at this sample (clearance < 0).
    m1: (S,) M_I flag (sample 0 and continuation samples False). m2: likewise for M_II.
    side: (sample, label) of M_VI or None.
    """

    traj: Trajectory
    positions: np.ndarray
    velocities: np.ndarray
    n_main: int
    collision: np.ndarray
    m1: np.ndarray
    m2: np.ndarray
    side: tuple[int, str] | None
    eps: float
    tau: float

    @property
    def n_samples(self) -> int:
        """The number of samples S drawn (main samples, then continuation samples)."""
        return self.positions.shape[0]

    def time(self, k: int) -> float:
        """The time [s] of sample ``k``: k·dt."""
        return k * self.traj.dt


def episode_view(traj: Trajectory, eps: float = 0.2, tau: float = 1.0) -> EpisodeView:
    """Computes everything drawn for ``traj`` (ε of M_I [m], τ of M_II [s])."""
    from socialnav.metrics.comfort import personal_space_flags, projected_path_flags

    cont = traj.continuation if traj.continuation is not None else np.zeros((0, traj.n_agents, 2))
    pos = np.concatenate([traj.positions, cont])
    vel = np.zeros_like(pos)
    if pos.shape[0] > 1:
        vel[1:] = np.diff(pos, axis=0) / traj.dt
        vel[0] = vel[1]
    n_main = traj.positions.shape[0]
    gap = np.linalg.norm(pos[:, 1:] - pos[:, :1], axis=-1) - traj.radii[1:] - traj.radii[0]
    collision = (gap < 0).any(axis=1) if traj.n_humans else np.zeros(pos.shape[0], dtype=bool)
    if traj.outcome == "collision":
        collision[n_main - 1] = True  # the simulator's swept test may catch a contact between samples
    m1 = np.zeros(pos.shape[0], dtype=bool)
    m2 = np.zeros(pos.shape[0], dtype=bool)
    if traj.n_humans and traj.n_steps:
        m1[1:n_main] = personal_space_flags(traj, eps)
        m2[1:n_main] = projected_path_flags(traj, tau)
    return EpisodeView(traj, pos, vel, n_main, collision, m1, m2, side_reading(traj), eps, tau)


def side_reading(traj: Trajectory) -> tuple[int, str] | None:
    """(sample, label) where M_VI reads its label (world frame), for single-human episodes."""
    from socialnav.metrics.sociability import side_preference

    if traj.n_humans != 1:
        return None
    band = traj.radii[1] + traj.radii[0]
    dy = traj.positions[:, 0, 1] - traj.positions[:, 1, 1]
    level = np.flatnonzero(dy >= -band)
    if level.size == 0:
        return None
    return int(level[0]), side_preference(traj, 1, "world") or "unlabelled"


def velocity_rectangle(p: np.ndarray, v: np.ndarray, r: float, tau: float) -> np.ndarray | None:
    """Corners (4, 2) of one agent's M_II rectangle, or None when it stands still."""
    from socialnav.metrics.comfort import velocity_rectangles

    corners, valid = velocity_rectangles(p[None], v[None], np.array([r]), tau)
    return corners[0] if valid[0] else None


#: How far beyond the agents [m] a drawing extends to show the walls around them: enough to see a
#: corridor's sides and a door's frame, while a wall running on for tens of metres is cut off.
WALL_CONTEXT = 2.0


def scene_bounds(traj: Trajectory, margin: float = 0.6) -> tuple[float, float, float, float]:
    """(xmin, xmax, ymin, ymax) [m] holding every sample, goal and disc, with a margin.

    Also the walls of the static map within ``WALL_CONTEXT`` of that.
    """
    pts = [traj.positions.reshape(-1, 2), traj.goals]
    if traj.continuation is not None:
        pts.append(traj.continuation.reshape(-1, 2))
    allp = np.concatenate(pts)
    allp = allp[np.isfinite(allp).all(axis=1)]
    pad = float(np.max(traj.radii)) + margin
    (x0, y0), (x1, y1) = allp.min(axis=0) - pad, allp.max(axis=0) + pad
    if traj.static_map is not None:
        vertices = np.concatenate(traj.static_map.polygons)
        edge = 0.3  # a wall on the frame's edge would be half drawn
        lo = np.maximum(vertices.min(axis=0) - edge, [x0 - WALL_CONTEXT, y0 - WALL_CONTEXT])
        hi = np.minimum(vertices.max(axis=0) + edge, [x1 + WALL_CONTEXT, y1 + WALL_CONTEXT])
        x0, y0 = min(x0, lo[0]), min(y0, lo[1])
        x1, y1 = max(x1, hi[0]), max(y1, hi[1])
    # no sliver plots (a single-human sweep is tall and thin): each span >= 3/4 of the other
    span = max(x1 - x0, y1 - y0) * 0.75
    if x1 - x0 < span:
        x0, x1 = (x0 + x1 - span) / 2, (x0 + x1 + span) / 2
    if y1 - y0 < span:
        y0, y1 = (y0 + y1 - span) / 2, (y0 + y1 + span) / 2
    return float(x0), float(x1), float(y0), float(y1)
