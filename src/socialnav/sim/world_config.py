"""The native world's configuration: WorldSettings translated for the core, and the World's size bounds.

:class:`~socialnav.sim.world.World` builds its ``_core.WorldConfig`` here; the native robot policies
(:mod:`socialnav.policies.native`) pass the same ORCA and social-force parameter values, so that a
robot steered by ORCA and the humans simulated by it read the same settings. A behaviour's values
travel as one list in its declared order (cpp/behaviours/), whatever the behaviour.
"""

from __future__ import annotations

import dataclasses

from socialnav import _core
from socialnav.settings import Settings
from socialnav.sim.behaviours import human_behaviour
from socialnav.sim.settings import WorldSettings

#: Memory one World may allocate for its state and recorded histories (docs/simulator.md, "Bounds").
MAX_WORLD_BYTES = 4 * 2**30
#: Native bytes per obstacle vertex and slot, for the memory check: the worst case, a different map in
#: every slot (slots with equal maps share one prepared copy). A vertex is held twice: as drawn (112
#: bytes with its edge arrays) and in ORCA's split map (137 with the tree), whose split points add a few
#: vertices per map (none to four in francis2023's): 320 allows half as many again.
OBSTACLE_VERTEX_BYTES = 320
#: The core's code of each kinematics (cpp/world.hpp, Kinematics).
KINEMATICS_CODES = {"holonomic": _core.HOLONOMIC, "unicycle": _core.UNICYCLE, "diff_drive": _core.DIFF_DRIVE}


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
    if human_behaviour(s.human_model).native:
        c.human_behaviour, c.human_params = s.human_model, parameter_values(s.human_parameters())
    else:  # a behaviour written in Python: the World gives the velocities (sim/python_humans.py)
        c.human_behaviour, c.human_params = "", []
    c.robot_visible = s.visibility == "visible"
    c.kinematics = KINEMATICS_CODES[s.kinematics]
    c.rotation_limit = s.rotation_limit
    c.max_linear_accel = s.diff_drive.max_linear_acceleration
    c.max_angular_accel = s.diff_drive.max_angular_acceleration
    c.max_reverse_speed = s.diff_drive.max_reverse_speed
    c.crowdsim_compat = s.crowdsim_compat
    c.discomfort_dist = s.reward.discomfort_dist
    c.success_reward = s.reward.success_reward
    c.collision_penalty = s.reward.collision_penalty
    c.discomfort_penalty_factor = s.reward.discomfort_penalty_factor
    c.continue_after_success = s.continue_after_success
    c.continuation_cap = s.continuation_cap
    c.max_obstacle_vertices = s.max_obstacle_vertices
    c.obstacle_collision_penalty = s.reward.resolved_obstacle_collision_penalty
    c.obstacle_collision_ends = s.obstacle_collision_ends
    c.human_routes = s.human_routes == "shortest"
    c.route_clearance = s.route_clearance
    return c


def sensing_config(settings: WorldSettings) -> _core.SensingConfig | None:
    """The core's sensing configuration of ``settings.sensing``; None for the defaults (exact, no lidar)."""
    s = settings.sensing
    if s.is_default:
        return None
    c = _core.SensingConfig()
    c.range = float("inf") if s.range is None else s.range
    c.fov, c.occlusion_walls, c.occlusion_humans = s.fov, s.occlusion_walls, s.occlusion_humans
    c.position_noise, c.velocity_noise, c.dropout, c.latency = (s.position_noise, s.velocity_noise, s.dropout,
                                                                s.latency)
    c.lidar_beams, c.lidar_fov, c.lidar_range, c.lidar_noise = (s.lidar_beams, s.lidar_fov, s.lidar_range,
                                                                s.lidar_noise)
    return c


def parameter_values(parameters: Settings) -> list[float]:
    """A behaviour's parameter values in declared order, as the core takes them.

    Args:
        parameters: An instance of the behaviour's settings class (``settings.orca``, ...).

    Returns:
        Its fields' values as floats, in field order (the order of the behaviour's declaration).
    """
    return [float(v) for v in dataclasses.astuple(parameters)]  # type: ignore[call-overload]


def orca_params(settings: WorldSettings) -> list[float]:
    """The ORCA parameter values of ``settings.orca``, as the core's ORCA robot policy takes them.

    Args:
        settings: Simulator semantics.

    Returns:
        The ``orca`` behaviour's values in declared order (neighbour distance [m] and count, time
        horizons [s], radius margin and safety space [m]).
    """
    return parameter_values(settings.orca)


def social_force_params(settings: WorldSettings) -> list[float]:
    """The social-force parameter values of ``settings.social_force``, as the core takes them.

    Args:
        settings: Simulator semantics (the field of view in degrees: the core converts it).

    Returns:
        The ``social_force`` behaviour's values in declared order.
    """
    return parameter_values(settings.social_force)
