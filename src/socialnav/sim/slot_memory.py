"""What a World's native slots remember of their episodes beyond the state arrays, to save and restore.

Routed humans (``human_routes``) hold their routes and giving-way timers, a delayed sensor
(``sensing.latency``) holds the past states its detections come from, and a differential-drive robot the
(v, ω) it drove last, from which its acceleration limits act. Saved with the episodes in flight
(train/ppo/worlds.py), they let a run resumed mid-episode go on as the uninterrupted one.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from socialnav import _core
    from socialnav.sim.settings import WorldSettings


class SlotMemory:
    """The World's route and sensing memory per slot (a part of :class:`~socialnav.sim.world.World`)."""

    # What the World holds and these methods read.
    batch_size: int
    settings: WorldSettings

    if TYPE_CHECKING:  # the World's own method

        def _native(self) -> _core.World: ...

    def route_state(self) -> list[np.ndarray]:
        """With ``human_routes``: where each slot's humans stand on their routes (one float array per slot).

        What decides where a routed human heads next besides the arrays of the state (its route, the point
        it heads for, its giving-way timers): saved with the episodes in flight, it lets a run resumed
        mid-episode go on as the uninterrupted one (train/ppo/worlds.py). Empty arrays without routes.
        """
        core = self._native()
        return [np.asarray(core.route_state(b), dtype=np.float64) for b in range(self.batch_size)]

    def sensing_state(self) -> list[np.ndarray]:
        """With ``sensing.latency``: each slot's record of the states its delayed detections come from.

        Saved with the episodes in flight like :meth:`route_state`; empty arrays without latency.
        """
        core = self._native()
        return [np.asarray(core.sensing_state(b), dtype=np.float64) for b in range(self.batch_size)]

    def set_sensing_state(self, state: list[np.ndarray]) -> None:
        """Puts back what :meth:`sensing_state` gave.

        Raises:
            ValueError: ``state`` does not have one entry per slot, or an entry has the wrong size.
        """
        if len(state) != self.batch_size:
            raise ValueError(f"sensing state: {len(state)} entries for {self.batch_size} slots")
        core = self._native()
        for b, entry in enumerate(state):
            core.set_sensing_state(b, np.ascontiguousarray(entry, dtype=np.float64))

    def set_route_state(self, state: list[np.ndarray]) -> None:
        """Puts back what :meth:`route_state` gave (after the slots' state and static maps).

        Raises:
            ValueError: ``state`` does not have one entry per slot, or an entry is malformed.
        """
        if len(state) != self.batch_size:
            raise ValueError(f"route state: {len(state)} entries for {self.batch_size} slots")
        core = self._native()
        for b, entry in enumerate(state):
            core.set_route_state(b, np.ascontiguousarray(entry, dtype=np.float64))

    def robot_twist(self, new_at_rest: bool = True) -> np.ndarray | None:
        """(B, 2) a differential-drive robot's (v [m/s], ω [rad/s]) of its last step; None otherwise.

        Args:
            new_at_rest: (0, 0) in slots whose episode has not stepped yet (every episode starts at rest);
                False: what each slot's robot last drove, the finished episode's until the slot steps.
        """
        if self.settings.kinematics != "diff_drive":
            return None
        out = np.empty((self.batch_size, 2))
        self._native().robot_twist(out, new_at_rest)
        return out

    def set_robot_twist(self, twist: np.ndarray) -> None:
        """Puts back what :meth:`robot_twist` gave (``new_at_rest=False``) into every slot.

        Raises:
            ValueError: The robot is not a differential drive, or ``twist`` is not (B, 2) finite values.
        """
        if self.settings.kinematics != "diff_drive":
            raise ValueError(f"robot twist: the robot is {self.settings.kinematics!r}, not diff_drive")
        twist = np.asarray(twist, dtype=np.float64)
        if twist.shape != (self.batch_size, 2):
            raise ValueError(f"robot twist: shape {twist.shape} for {self.batch_size} slots, not (B, 2)")
        core = self._native()
        for b, (v, omega) in enumerate(twist):
            core.set_robot_twist(b, float(v), float(omega))
