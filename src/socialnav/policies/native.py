"""Robot policies that need no learning: linear, ORCA and social force, batched in native code."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from socialnav import _core
from socialnav.policies.registry import register_policy
from socialnav.sim.observation import Observation, check_observation
from socialnav.sim.pool import shared_pool
from socialnav.sim.settings import OrcaSettings, SocialForceSettings, WorldSettings
from socialnav.sim.world import orca_params, social_force_params
from socialnav.sim.world_config import KINEMATICS_CODES


class NativePolicy:
    """A robot policy computed by the native core from observations.

    The ORCA and social-force policies avoid the observation's static obstacles the way the humans
    of the same model do (RVO2's obstacle algorithm; Helbing & Molnár's wall repulsion); the linear
    policy ignores them, as linear humans do.

    The ``_route`` kinds head for the first point of the shortest route around the walls from where the
    robot stands (re-planned every step; docs/routes.md) instead of the goal itself: Francis et al.'s
    "global planner + local avoidance" baseline. On an open floor they act as their plain kinds.

    Their command is a velocity; a unicycle turns towards it and drives at its speed (CrowdSim's rule), a
    differential drive turns towards it and drives its component along the heading (docs/kinematics.md).

    Args:
        kind: "linear", "orca", "orca_route", "social_force" or "social_force_route".
        safety_space: ORCA only: inflation of the robot's and every human's radius [m].
        route_clearance: the ``_route`` kinds: distance [m] kept from walls beyond the robot's (inflated)
            radius where the passage allows.
        orca: ORCA parameters (CrowdSim's by default).
        social_force: social-force parameters (Helbing & Molnár's by default).
        threads: native worker threads (0 = all cores, at most 8).
    """

    information = "none"

    def __init__(
        self,
        kind: str,
        safety_space: float = 0.0,
        orca: OrcaSettings | None = None,  # type: ignore[valid-type]
        social_force: SocialForceSettings | None = None,  # type: ignore[valid-type]
        threads: int = 0,
        route_clearance: float = 0.1,
    ):
        if safety_space < 0:
            raise ValueError(f"safety_space must be >= 0, got {safety_space}")
        if not 0 <= route_clearance <= 10:
            raise ValueError(f"route_clearance must be in [0, 10] m, got {route_clearance}")
        self.route_clearance = float(route_clearance)
        self.name = kind
        self.kind = kind
        self.safety_space = float(safety_space)
        settings = WorldSettings(
            orca=orca or OrcaSettings(), social_force=social_force or SocialForceSettings(), threads=threads
        )
        self._threads = threads
        self._configure(settings)
        self._pool = shared_pool(settings.resolved_threads)  # the worlds' pool (sim/pool.py)
        self._out: np.ndarray | None = None

    def _configure(self, settings: WorldSettings) -> None:
        self._orca_settings = settings.orca
        # The humans' ORCA and social-force parameter values, in their behaviours' declared order.
        self._orca = orca_params(settings)
        self._social_force = social_force_params(settings)
        self.rotation_limit = float(settings.rotation_limit)
        self.max_reverse_speed = float(settings.diff_drive.max_reverse_speed)

    def use_world(self, world: WorldSettings) -> NativePolicy:
        """Takes the world's ORCA and social-force parameters, rotation limit and reverse speed.

        ``build_policy`` calls it with the preset's world; a policy made with ``make_policy`` for a
        ``World`` of other settings gets them with ``policy.use_world(world.settings)``.

        Returns:
            The policy itself.
        """
        self._configure(dataclasses.replace(world, threads=self._threads))
        return self

    def act(self, observation: Observation) -> np.ndarray:
        """(B, 2) actions in the world's format for the observed batch (zeros where inactive)."""
        check_observation(observation, self.name)  # a NaN human was dropped by ORCA, NaN from social force
        B = observation.batch_size
        if self._out is None or self._out.shape[0] != B:
            self._out = np.zeros((B, 2))
        kinematics = KINEMATICS_CODES[observation.kinematics]
        _core.robot_actions(
            self.kind,
            np.ascontiguousarray(observation.robot),
            np.ascontiguousarray(observation.humans),
            np.ascontiguousarray(observation.human_mask),
            np.ascontiguousarray(observation.active),
            kinematics,
            self.rotation_limit,
            observation.dt,
            self._orca,
            self.safety_space,
            self._social_force,
            self._pool,
            self._out,
            None if observation.obstacles is None else observation.obstacles.native,
            self.route_clearance,
            self.max_reverse_speed,
        )
        return self._out.copy()

    def describe(self) -> dict[str, Any]:
        """The record stored with results.

        Policy, information, ORCA's safety space [m], and for the ``_route`` kinds their route clearance [m].
        """
        record = {"policy": self.name, "information": self.information, "safety_space": self.safety_space}
        if self.kind.endswith("_route"):
            record["route_clearance"] = self.route_clearance
        return record


@register_policy(
    "linear", description="straight to the goal at v_pref, ignoring humans", parameters={"threads": 0}
)
def linear(threads: int = 0) -> NativePolicy:
    """Straight to the goal at v_pref, ignoring humans (the native C++ policy).

    Args:
        threads: Native threads over the batch (0: one per core).

    Returns:
        The policy.
    """
    return NativePolicy("linear", threads=threads)


@register_policy(
    "orca",
    description="ORCA (van den Berg et al. 2011) towards the goal, CrowdNav's ORCA policy",
    parameters={"safety_space": 0.2, "threads": 0},
)
def orca(safety_space: float = 0.2, threads: int = 0) -> NativePolicy:
    """ORCA (van den Berg et al. 2011) as the robot's policy (the native C++ solver).

    Args:
        safety_space: Extra clearance [m] added to the robot's radius in ORCA's constraints.
        threads: Native threads over the batch (0: one per core).

    Returns:
        The policy.
    """
    return NativePolicy("orca", safety_space=safety_space, threads=threads)


@register_policy(
    "social_force",
    description="social force model (Helbing & Molnár 1995) towards the goal",
    parameters={"threads": 0},
)
def social_force(threads: int = 0) -> NativePolicy:
    """The social force model (Helbing and Molnár 1995) as the robot's policy (native C++).

    Args:
        threads: Native threads over the batch (0: one per core).

    Returns:
        The policy.
    """
    return NativePolicy("social_force", threads=threads)


@register_policy(
    "orca_route",
    description="ORCA towards the first point of the shortest route around the walls (global planner + local "
    "avoidance)",
    parameters={"safety_space": 0.2, "route_clearance": 0.1, "threads": 0},
)
def orca_route(safety_space: float = 0.2, route_clearance: float = 0.1, threads: int = 0) -> NativePolicy:
    """ORCA following the shortest route around the walls, re-planned every step (docs/routes.md).

    The classical baseline Francis et al. (2023) ask for beside learned ones: a global planner (a
    visibility graph over the walls' corners, Lozano-Pérez & Wesley 1979) and a local one (ORCA, van den
    Berg et al. 2011). On an open floor it is the ``orca`` policy.

    Args:
        safety_space: Extra clearance [m] added to the robot's radius in ORCA's constraints.
        route_clearance: Distance [m] the route keeps from walls beyond the inflated radius, where the
            passage allows (narrower passages: the radius alone).
        threads: Native threads over the batch (0: one per core).

    Returns:
        The policy.
    """
    return NativePolicy("orca_route", safety_space=safety_space, threads=threads,
                        route_clearance=route_clearance)


@register_policy(
    "social_force_route",
    description="social force towards the first point of the shortest route around the walls",
    parameters={"route_clearance": 0.1, "threads": 0},
)
def social_force_route(route_clearance: float = 0.1, threads: int = 0) -> NativePolicy:
    """The social force model following the shortest route around the walls (docs/routes.md).

    Args:
        route_clearance: Distance [m] the route keeps from walls beyond the robot's radius, where the
            passage allows.
        threads: Native threads over the batch (0: one per core).

    Returns:
        The policy.
    """
    return NativePolicy("social_force_route", threads=threads, route_clearance=route_clearance)
