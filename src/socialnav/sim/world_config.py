"""The native world's configuration: WorldSettings translated for the core, and the World's size bounds.

:class:`~socialnav.sim.world.World` builds its ``_core.WorldConfig`` here; the native robot policies
(:mod:`socialnav.policies.native`) share the ORCA and social-force parameter translation, so that a
robot steered by ORCA and the humans simulated by it read the same settings.
"""

from __future__ import annotations

import numpy as np

from socialnav import _core
from socialnav.sim.settings import WorldSettings

#: Memory one World may allocate for its state and recorded histories (docs/simulator.md, "Bounds").
MAX_WORLD_BYTES = 4 * 2**30
#: Native bytes per obstacle vertex and slot, for the memory check: the worst case, a different map in
#: every slot (slots with equal maps share one prepared copy).
OBSTACLE_VERTEX_BYTES = 128

#: The core's code of each human motion model (``WorldSettings.human_model``).
HUMAN_MODEL_IDS = {
    "orca": _core.HUMAN_ORCA,
    "social_force": _core.HUMAN_SOCIAL_FORCE,
    "linear": _core.HUMAN_LINEAR,
}


def world_bytes(settings: WorldSettings, batch_size: int, n_agents: int, record: bool = True) -> int:
    """Bytes a World allocates for its state and, when recording, its histories.

    Args:
        settings: The world's settings (their ``history_length`` sizes the histories).
        batch_size: Number of slots B.
        n_agents: Agents per slot A (1 robot + N humans).
        record: Whether the world keeps per-episode histories.

    Returns:
        The allocation in bytes.
    """
    T = settings.history_length() if record else 0
    return int(batch_size) * (int(n_agents) * (8 * 8 + 8 + 1) + 64 + int(T) * (int(n_agents) * 32 + 8))


def check_world_size(settings: WorldSettings, batch_size: int, n_agents: int, record: bool = True) -> None:
    """Refuses a World larger than :data:`MAX_WORLD_BYTES` before anything is allocated.

    Args:
        settings: The world's settings.
        batch_size: Number of slots B.
        n_agents: Agents per slot A (1 robot + N humans).
        record: Whether the world keeps per-episode histories.

    Raises:
        ValueError: The world would need more than :data:`MAX_WORLD_BYTES`; the message names the
            batch size, agents and steps, and what to lower.
    """
    need = world_bytes(settings, batch_size, n_agents, record)
    if need > MAX_WORLD_BYTES:
        raise ValueError(
            f"a world of {batch_size} episodes x {n_agents} agents x {settings.history_length()} steps "
            f"needs {need / 2**30:.1f} GiB, more than the {MAX_WORLD_BYTES / 2**30:.0f} GiB allowed "
            "(lower the batch size, the number of humans, or time_limit / dt)"
        )


def check_map_size(n_vertices: int, batch_size: int) -> None:
    """Refuses a static map whose native copies in every slot would exceed :data:`MAX_WORLD_BYTES`.

    Args:
        n_vertices: Vertices of the map.
        batch_size: Number of slots B (the worst case: a different map in each).

    Raises:
        ValueError: The copies would need more than :data:`MAX_WORLD_BYTES`.
    """
    need = batch_size * n_vertices * OBSTACLE_VERTEX_BYTES
    if need > MAX_WORLD_BYTES:
        raise ValueError(
            f"a static map of {n_vertices} vertices in each of {batch_size} slots "
            f"needs {need / 2**30:.1f} GiB, more than the {MAX_WORLD_BYTES / 2**30:.0f} GiB allowed "
            "(lower the batch size or simplify the map)"
        )


def world_config(
    settings: WorldSettings, batch_size: int, n_agents: int, history_len: int
) -> _core.WorldConfig:
    """The core's configuration of a world.

    Args:
        settings: Simulator semantics.
        batch_size: Number of slots B.
        n_agents: Agents per slot A (1 robot + N humans).
        history_len: Recorded steps per episode T (0: not recording).

    Returns:
        The ``_core.WorldConfig`` the native world is built with.
    """
    s = settings
    c = _core.WorldConfig()
    c.batch, c.agents, c.history_len, c.threads = batch_size, n_agents, history_len, s.resolved_threads
    c.dt, c.time_limit = s.dt, s.time_limit
    c.human_model = HUMAN_MODEL_IDS[s.human_model]
    c.robot_visible = s.visibility == "visible"
    c.kinematics = _core.HOLONOMIC if s.kinematics == "holonomic" else _core.UNICYCLE
    c.rotation_limit = s.rotation_limit
    c.crowdsim_compat = s.crowdsim_compat
    c.discomfort_dist = s.reward.discomfort_dist
    c.success_reward = s.reward.success_reward
    c.collision_penalty = s.reward.collision_penalty
    c.discomfort_penalty_factor = s.reward.discomfort_penalty_factor
    c.orca = orca_params(s)
    c.orca_radius_margin = s.orca.radius_margin
    c.human_safety_space = s.orca.safety_space
    c.social_force = social_force_params(s)
    c.continue_after_success = s.continue_after_success
    c.continuation_cap = s.continuation_cap
    c.max_obstacle_vertices = s.max_obstacle_vertices
    c.obstacle_collision_penalty = s.reward.resolved_obstacle_collision_penalty
    c.obstacle_collision_ends = s.obstacle_collision_ends
    return c


def orca_params(settings: WorldSettings) -> _core.OrcaParams:
    """The core's ORCA parameters from ``settings.orca``.

    Args:
        settings: Simulator semantics.

    Returns:
        The ``_core.OrcaParams`` (neighbour distance [m] and count, time horizons [s]).
    """
    p = _core.OrcaParams()
    p.neighbor_dist = settings.orca.neighbor_dist
    p.max_neighbors = settings.orca.max_neighbors
    p.time_horizon = settings.orca.time_horizon
    p.time_horizon_obst = settings.orca.time_horizon_obst
    return p


def social_force_params(settings: WorldSettings) -> _core.SocialForceParams:
    """The core's social-force parameters from ``settings.social_force``.

    Args:
        settings: Simulator semantics (the field of view is given in degrees there).

    Returns:
        The ``_core.SocialForceParams``, the field of view's half angle in radians.
    """
    sf = settings.social_force
    p = _core.SocialForceParams()
    p.relaxation_time, p.v0, p.sigma, p.step_time = sf.relaxation_time, sf.v0, sf.sigma, sf.step_time
    p.fov_half_angle = float(np.deg2rad(sf.fov_half_angle))
    p.outside_fov_weight, p.max_speed_factor = sf.outside_fov_weight, sf.max_speed_factor
    p.wall_u0, p.wall_r = sf.wall_u0, sf.wall_r
    return p
