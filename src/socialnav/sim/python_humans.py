"""Humans moved by a pedestrian behaviour written in Python: the World's side of the Python path.

A world whose ``human_model`` is a :class:`~socialnav.sim.behaviours.HumanBehaviour` (registered from
outside the package) is built with no native behaviour (``_core.WorldConfig.human_behaviour == ""``):
before each native step, and before the oracle's preview, the World calls :meth:`PythonHumans.give`,
which asks the behaviour for the velocities of every human of the batch in one vectorised call and
writes them where the core reads them. The rest of the step (robot, collisions, rewards, refills)
stays native. The cost is one Python call and a few array copies per step of the whole batch
(docs/extending.md).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from socialnav import _core
from socialnav.sim.behaviours import HumanBehaviour, HumanState, human_behaviour

if TYPE_CHECKING:
    from socialnav.sim.settings import WorldSettings

__all__ = ["PythonHumans", "human_state", "python_humans"]


def _read_only(array: np.ndarray) -> np.ndarray:
    view = array.view()
    view.flags.writeable = False
    return view


def human_state(world: Any) -> HumanState:
    """What a Python behaviour sees of a World's batch (read-only views of its arrays).

    Args:
        world: A :class:`~socialnav.sim.world.World`.

    Returns:
        The humans of its B slots; ``mask`` holds the real humans of slots whose episode runs.
    """
    live = (world.status == _core.STATUS_RUNNING) | (world.status == _core.STATUS_CONTINUING)
    settings = world.settings
    return HumanState(
        position=_read_only(world.position[:, 1:]),
        velocity=_read_only(world.velocity[:, 1:]),
        goal=_read_only(world.goal[:, 1:]),
        radius=_read_only(world.radius[:, 1:]),
        v_pref=_read_only(world.v_pref[:, 1:]),
        mask=world.mask[:, 1:].astype(bool) & live[:, None],
        robot_position=_read_only(world.position[:, 0]),
        robot_velocity=_read_only(world.velocity[:, 0]),
        robot_radius=_read_only(world.radius[:, 0]),
        robot_visible=settings.visibility == "visible",
        dt=float(settings.dt),
        static_maps=tuple(world.static_maps),
        time=_read_only(world.steps * float(settings.dt)),
        episode=_read_only(world.episode_index),
    )


class PythonHumans:
    """Hands a native world the velocities a Python behaviour gives its humans.

    Args:
        behaviour: The behaviour with its parameters.
        core: The native world (built with ``human_behaviour == ""``).
        batch: Slots B.
        agents: Agents per slot A.
    """

    def __init__(self, behaviour: HumanBehaviour, core: _core.World, batch: int, agents: int):
        self.behaviour = behaviour
        self.velocity = np.zeros((batch, agents, 2))  # what the core reads (the robot's column unused)
        core.give_human_velocities(self.velocity)

    def give(self, world: Any) -> None:
        """Asks the behaviour for the humans' next velocities and writes them for the core.

        Args:
            world: The :class:`~socialnav.sim.world.World` about to step (or to preview its humans).

        Raises:
            ValueError: The behaviour returned an array of another shape, or a non-finite velocity for
                a human it moves (the behaviour, the episode, its slot and the time are named).
            RuntimeError: The behaviour raised (named, its exception chained).
        """
        state = human_state(world)
        name = type(self.behaviour).name
        try:
            preferred = np.asarray(self.behaviour.preferred_velocity(state), dtype=np.float64)
            out = np.asarray(self.behaviour.velocities(state, preferred), dtype=np.float64)
        except Exception as exc:  # the behaviour's own failure, said with whose it is
            raise RuntimeError(f"pedestrian behaviour {name!r} failed: {type(exc).__name__}: {exc}") from exc
        shape = state.position.shape
        if out.shape != shape:
            raise ValueError(f"pedestrian behaviour {name!r}: velocities must have shape {shape} (B, N, 2), "
                             f"got {out.shape}")
        bad = state.mask & ~np.isfinite(out).all(axis=-1)
        if bad.any():
            slot, human = (int(i) for i in np.argwhere(bad)[0])
            episode, at = int(state.episode[slot]), float(state.time[slot])
            velocity = tuple(float(v) for v in out[slot, human])
            raise ValueError(f"pedestrian behaviour {name!r} gave human {human} of episode {episode} (slot "
                             f"{slot}) at t = {at:g} s the non-finite velocity {velocity}")
        np.copyto(self.velocity[:, 1:], np.where(state.mask[..., None], out, 0.0))


def python_humans(settings: WorldSettings, core: _core.World, batch: int, agents: int) -> PythonHumans | None:
    """The Python side of a world whose humans follow a Python behaviour, None for a native one.

    Args:
        settings: The world's settings (``human_model``, ``human_params``).
        core: The native world.
        batch: Slots B.
        agents: Agents per slot A.

    Returns:
        A :class:`PythonHumans`, or None where the core moves the humans itself.
    """
    if human_behaviour(settings.human_model).native:
        return None
    behaviour = settings.human_parameters()
    assert isinstance(behaviour, HumanBehaviour)
    return PythonHumans(behaviour, core, batch, agents)
