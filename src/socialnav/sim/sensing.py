"""The robot's sensors for one pose: the lidar scan and the occlusion rule the world's observation uses.

The world computes both natively for every episode of a batch (``WorldSettings.sensing``,
docs/perception.md); these functions give the same answers for one pose and a map, to check a reading
by hand or to draw it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from socialnav import _core
from socialnav.maps.static_map import StaticMap

__all__ = ["disc_in_sight", "lidar_beam_angles", "lidar_scan"]


def _flat(static_map: StaticMap | None) -> tuple[np.ndarray, np.ndarray]:
    if not static_map:
        return np.zeros((0, 2)), np.zeros(1, dtype=np.int64)
    return static_map.to_flat()


def _discs(positions: Sequence | np.ndarray | None, radii: Sequence | np.ndarray | None):
    # copies: the core takes writable C-contiguous arrays, and a trajectory's arrays are read-only views
    pos = np.array(np.zeros((0, 2)) if positions is None else positions, dtype=np.float64).reshape(-1, 2)
    rad = np.array(np.zeros(0) if radii is None else radii, dtype=np.float64)
    if pos.ndim != 2 or pos.shape[1] != 2 or rad.shape != (pos.shape[0],):
        raise ValueError(f"disc positions must be (n, 2) and radii (n,), got {pos.shape} and {rad.shape}")
    return pos, rad


def lidar_beam_angles(beams: int, fov: float = 2 * math.pi) -> np.ndarray:
    """The beams' angles [rad] relative to the sensor's heading (docs/perception.md, "The lidar").

    Over the full circle -pi + i 2pi/n; over a sector -fov/2 + i fov/(n - 1); one beam: 0.
    """
    return np.asarray(_core.lidar_beam_angles(int(beams), float(fov)))


def lidar_scan(eye: Sequence[float], heading: float, beams: int, static_map: StaticMap | None = None,
               disc_positions: Sequence | np.ndarray | None = None,
               disc_radii: Sequence | np.ndarray | None = None, *, fov: float = 2 * math.pi,
               max_range: float = 10.0) -> np.ndarray:
    """One scan from ``eye``: per beam the distance [m] to the nearest wall edge or disc.

    A beam that hits nothing reads ``max_range``.

    Args:
        eye: (2,) the sensor's position [m].
        heading: The direction beam angles are measured from [rad].
        beams: The number of beams (>= 1).
        static_map: The walls (None: an open floor).
        disc_positions: (n, 2) centres of the discs (people) [m].
        disc_radii: (n,) their radii [m].
        fov: The beams' sector [rad], in (0, 2 pi].
        max_range: The reading of a beam that hits nothing [m].

    Returns:
        (beams,) float64 distances (the world's observation holds them as float32).

    Raises:
        ValueError: ``beams`` < 1, ``fov`` outside (0, 2 pi], or mis-shaped discs.
    """
    vertices, offsets = _flat(static_map)
    pos, rad = _discs(disc_positions, disc_radii)
    return np.asarray(_core.lidar_scan(np.array(eye, dtype=np.float64), float(heading), int(beams),
                                       float(fov), float(max_range), pos, rad, vertices, offsets))


def disc_in_sight(eye: Sequence[float], centre: Sequence[float], radius: float,
                  static_map: StaticMap | None = None, other_positions: Sequence | np.ndarray | None = None,
                  other_radii: Sequence | np.ndarray | None = None) -> bool:
    """Whether some point of the disc is in sight from ``eye`` past the walls and the other discs.

    The occlusion rule of the robot's detections (``sensing.occlusion_walls`` / ``occlusion_humans``):
    a human half behind a corner is in sight, one entirely behind it is not.
    """
    vertices, offsets = _flat(static_map)
    pos, rad = _discs(other_positions, other_radii)
    return bool(_core.disc_in_sight(np.array(eye, dtype=np.float64), np.array(centre, dtype=np.float64),
                                    float(radius), pos, rad, vertices, offsets))
