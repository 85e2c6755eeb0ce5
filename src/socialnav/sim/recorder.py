"""Turns finished episodes into Trajectory objects.

The native core writes each step's sample into per-slot history buffers (allocated once), so the
recorder only slices the finished slots' histories: nothing is copied for running episodes.
"""

from __future__ import annotations

import json
from typing import TYPE_CHECKING

import numpy as np

from socialnav import _core
from socialnav.trajectory import Trajectory

if TYPE_CHECKING:
    from socialnav.sim.world import World

OUTCOME_NAMES = {
    _core.STATUS_SUCCESS: "success",
    _core.STATUS_COLLISION: "collision",
    _core.STATUS_TIMEOUT: "timeout",
}
#: Why a collision happened (the trajectory's settings["collision_kind"]).
COLLISION_KIND_NAMES = {
    _core.COLLISION_HUMAN: "human",
    _core.COLLISION_OBSTACLE: "obstacle",
}


class Recorder:
    """Reads finished slots' histories out of a World.

    Args:
        world: The world whose slots are recorded.
        hist_position, hist_velocity: (B, T, A, 2) buffers the core writes.
        hist_dmin: (B, T) swept minimum clearance per step (entry k for step k).
        tags: Settings stored in every trajectory besides the world's own.
    """

    def __init__(
        self,
        world: World,
        hist_position: np.ndarray,
        hist_velocity: np.ndarray,
        hist_dmin: np.ndarray,
        tags: dict,
    ):
        self.world = world
        self.hist_position = hist_position
        self.hist_velocity = hist_velocity
        self.hist_dmin = hist_dmin
        s = world.settings
        recorded = {
            "scenario": getattr(world.scenario, "name", type(world.scenario).__name__),
            "split": world.stream.split,
            "visibility": s.visibility,
            "human_model": s.human_model,
            "orca_mode": s.orca_mode,
            "kinematics": s.kinematics,
            "crowdsim_compat": s.crowdsim_compat,
            "time_limit": s.time_limit,
        }
        if s.human_routes != "none":  # recorded where routes are on only: other records stay as they were
            recorded.update(human_routes=s.human_routes, route_clearance=s.route_clearance)
        if not s.sensing.is_default:  # what the robot perceived (docs/perception.md); likewise only when set
            recorded["sensing"] = s.sensing.to_dict()
        per_episode = ("index", "seed", "collision_kind")  # set by collect()
        clash = sorted(set(tags) & {*recorded, *per_episode})
        if clash:
            raise ValueError(f"tags {clash} would overwrite what the world records of each episode "
                             f"({', '.join([*recorded, *per_episode])}); give them other names")
        try:
            json.dumps(tags)
        except (TypeError, ValueError) as err:
            raise ValueError(f"tags must be JSON data (they are written with each trajectory): {err}") \
                from None
        self.base_settings = {**recorded, **tags}

    def collect(self, slots: np.ndarray) -> list[Trajectory]:
        """Trajectories of the given finished slots (call before the slots are refilled)."""
        w = self.world
        out = []
        for b in slots:
            b = int(b)
            agents = np.flatnonzero(w.mask[b])
            end = int(w.end_step[b])  # the robot's episode ends at sample `end`
            total = int(w.steps[b])
            positions = self.hist_position[b, : end + 1][:, agents].copy()
            velocities = self.hist_velocity[b, : end + 1][:, agents].copy()
            continuation = None
            if total > end:
                continuation = self.hist_position[b, end + 1 : total + 1][:, agents].copy()
            roles = ("robot",) + ("human",) * (len(agents) - 1)
            settings = {
                **self.base_settings,
                "index": int(w.episode_index[b]),
                "seed": int(w.episode_seed[b]),
            }
            if int(w.status[b]) == _core.STATUS_COLLISION:
                settings["collision_kind"] = COLLISION_KIND_NAMES[int(w.collision_kind[b])]
            out.append(
                Trajectory(
                    dt=w.settings.dt,
                    positions=positions,
                    velocities=velocities,
                    radii=w.radius[b, agents].copy(),
                    goals=w.goal[b, agents].copy(),
                    v_pref=w.v_pref[b, agents].copy(),
                    roles=roles,
                    outcome=OUTCOME_NAMES[int(w.status[b])],
                    min_clearance=self.hist_dmin[b, 1 : end + 1].copy(),
                    continuation=continuation,
                    human_overlaps=None if w.settings.crowdsim_compat else int(w.overlaps[b]),
                    settings=settings,
                    static_map=w.static_maps[b],
                )
            )
        return out
