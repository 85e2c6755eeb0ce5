"""One ORCA step with static obstacles, for checking the core against RVO2 or any other ORCA.

:func:`orca_step` runs the native solver the world's ORCA humans use (van den Berg, Guy, Lin,
Manocha, "Reciprocal n-body collision avoidance", ISRR 2011, with the RVO2 library's obstacle
algorithm) on one set of agents, the way RVO2's ``RVOSimulator::doStep`` computes new velocities
before it moves anyone: every agent selects its neighbours (the ``max_neighbors`` closest strictly
within ``neighbor_dist``) and its obstacle edges (those facing it within
``time_horizon_obst * max_speed + radius``), then solves its linear program. See docs/walls.md.
"""

from __future__ import annotations

import numpy as np

from socialnav import _core
from socialnav.maps.static_map import StaticMap

__all__ = ["orca_step"]


def _array(value: object, name: str, shape: tuple[int, ...]) -> np.ndarray:
    arr = np.ascontiguousarray(value, dtype=np.float64)
    if arr.shape != shape:
        raise ValueError(f"orca_step: {name} must have shape {shape}, got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"orca_step: {name} contains a non-finite value")
    return arr


def orca_step(
    positions: np.ndarray,
    velocities: np.ndarray,
    pref_velocities: np.ndarray,
    radii: np.ndarray,
    max_speeds: np.ndarray,
    static_map: StaticMap | None = None,
    *,
    time_step: float = 0.25,
    time_horizon: float = 5.0,
    time_horizon_obst: float = 5.0,
    neighbor_dist: float = 10.0,
    max_neighbors: int = 10,
) -> np.ndarray:
    """New velocities of n agents after one ORCA step among each other and static obstacles.

    Args:
        positions: (n, 2) [m].
        velocities: (n, 2) current velocities [m/s] (RVO2's ``velocity_``).
        pref_velocities: (n, 2) preferred velocities [m/s].
        radii: (n,) [m], used as given (the world adds CrowdSim's 1 cm margin before calling the
            same solver; add it yourself to reproduce the world).
        max_speeds: (n,) [m/s], the radius of each agent's velocity disc.
        static_map: The obstacles, or None for none. A 2-vertex polygon is a two-sided wall (RVO2's
            degenerate polygon a -> b -> a); a polygon of k >= 3 vertices is solid (counter-clockwise).
        time_step: RVO2's ``timeStep`` [s] (resolves overlaps between agents within one step).
        time_horizon: tau for other agents [s].
        time_horizon_obst: tau for obstacles [s].
        neighbor_dist: Neighbour search range [m].
        max_neighbors: Neighbours considered per agent, in [0, 64].

    Returns:
        (n, 2) new velocities [m/s]; positions are not advanced.

    Raises:
        ValueError: naming the argument with a wrong shape, a non-finite value or a value out of range.
    """
    positions = np.asarray(positions, dtype=np.float64)
    if positions.ndim != 2 or positions.shape[1] != 2:
        raise ValueError(f"orca_step: positions must have shape (n, 2), got {positions.shape}")
    n = positions.shape[0]
    positions = _array(positions, "positions", (n, 2))
    velocities = _array(velocities, "velocities", (n, 2))
    pref_velocities = _array(pref_velocities, "pref_velocities", (n, 2))
    radii = _array(radii, "radii", (n,))
    max_speeds = _array(max_speeds, "max_speeds", (n,))
    if (radii < 0).any():
        raise ValueError(f"orca_step: radii must be >= 0, got {radii.min()}")
    if (max_speeds < 0).any():
        raise ValueError(f"orca_step: max_speeds must be >= 0, got {max_speeds.min()}")
    for name, value in (
        ("time_step", time_step),
        ("time_horizon", time_horizon),
        ("time_horizon_obst", time_horizon_obst),
        ("neighbor_dist", neighbor_dist),
    ):
        number = isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool)
        if not (number and np.isfinite(value) and value > 0):
            raise ValueError(f"orca_step: {name} must be a finite number > 0, got {value!r}")
    if (isinstance(max_neighbors, bool) or not isinstance(max_neighbors, int | np.integer)
            or not 0 <= max_neighbors <= 64):
        raise ValueError(f"orca_step: max_neighbors must be an integer in [0, 64], got {max_neighbors!r}")
    if static_map is not None and not isinstance(static_map, StaticMap):
        raise TypeError(f"orca_step: static_map must be a StaticMap or None, got {type(static_map).__name__}")
    if static_map:
        vertices, offsets = static_map.to_flat()
    else:
        vertices, offsets = np.zeros((0, 2)), np.zeros(1, dtype=np.int64)
    # The ORCA behaviour's parameters by name (the others keep their defaults; radii are used as given).
    params = {"neighbor_dist": float(neighbor_dist), "max_neighbors": int(max_neighbors),
              "time_horizon": float(time_horizon), "time_horizon_obst": float(time_horizon_obst)}
    out = np.zeros((n, 2))
    _core.orca_step(
        positions, velocities, pref_velocities, radii, max_speeds, params, float(time_step),
        vertices, offsets, out,
    )
    return out
