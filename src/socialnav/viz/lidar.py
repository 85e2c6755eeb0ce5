"""The robot's lidar drawn with an episode (the ``lidar`` overlay of ``socialnav render``).

A trajectory records positions, not scans, so the scan of sample k is computed again from the sample:
the world's own scan (:func:`socialnav.sim.lidar_scan`, docs/perception.md) from the robot's centre,
against the episode's walls and the discs of the humans present, with the lidar the episode's world
had (``settings["sensing"]``: beams, sector and range; 360 beams over the full circle and 10 m where it
had none). The heading is the robot's direction of travel at that sample (towards its goal while it
stands), which is the lidar's heading for a holonomic robot and a unicycle's heading whenever it moves.
Readings are drawn without the world's noise.
"""

from __future__ import annotations

import math

import numpy as np

from socialnav.trajectory import Trajectory
from socialnav.viz.geometry import EpisodeView

#: The lidar drawn where the episode's world had none: beams, sector [rad], range [m].
DEFAULT_LIDAR = (360, 2 * math.pi, 10.0)


def lidar_of(traj: Trajectory) -> tuple[int, float, float]:
    """(beams, sector [rad], range [m]) of the episode's lidar, :data:`DEFAULT_LIDAR` where it had none."""
    sensing = (traj.settings or {}).get("sensing") or {}
    beams = int(sensing.get("lidar_beams", 0) or 0)
    if not beams:
        return DEFAULT_LIDAR
    return beams, float(sensing.get("lidar_fov", 2 * math.pi)), float(sensing.get("lidar_range", 10.0))


def scan_at(view: EpisodeView, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The robot's centre (2,) and the (beams, 2) points where its lidar's beams end at sample ``k``."""
    from socialnav.sim.sensing import lidar_beam_angles, lidar_scan

    traj = view.traj
    beams, fov, max_range = lidar_of(traj)
    eye = view.positions[k, 0]
    v = view.velocities[k, 0]
    to_goal = traj.goals[0] - eye
    heading = math.atan2(v[1], v[0]) if np.hypot(*v) > 1e-9 else math.atan2(to_goal[1], to_goal[0])
    present = np.ones(traj.n_agents, dtype=bool)
    if traj.present is not None and k < traj.present.shape[0]:
        present = traj.present[k].astype(bool)
    humans = np.flatnonzero(present[1:]) + 1
    ranges = lidar_scan(eye, heading, beams, traj.static_map, view.positions[k, humans], traj.radii[humans],
                        fov=fov, max_range=max_range)
    angles = heading + lidar_beam_angles(beams, fov)
    return eye, eye + ranges[:, None] * np.stack([np.cos(angles), np.sin(angles)], axis=1)


def draw_scan(ax, view: EpisodeView, k: int) -> tuple:
    """The scan of sample ``k``: faint rays and a dot where each beam ends; returns the two artists."""
    from matplotlib.collections import LineCollection

    eye, ends = scan_at(view, k)
    rays = LineCollection([[eye, e] for e in ends], colors="#2a9d8f", linewidths=0.4, alpha=0.25)
    ax.add_collection(rays)
    (dots,) = ax.plot(ends[:, 0], ends[:, 1], ".", color="#2a9d8f", ms=2.0, alpha=0.9)
    return rays, dots


def move_scan(artists: tuple, view: EpisodeView, k: int) -> None:
    """Moves :func:`draw_scan`'s artists to the scan of sample ``k``."""
    rays, dots = artists
    eye, ends = scan_at(view, k)
    rays.set_segments([[eye, e] for e in ends])
    dots.set_data(ends[:, 0], ends[:, 1])
