"""World settings: the simulator's semantics as data (docs/simulator.md).

Defaults are CrowdSim's. Every deviation from CrowdSim is a named field; ``crowdsim_compat``
restores CrowdSim's quirks (late timeout taking precedence, collision sweep with the humans'
previous velocities, no human-human overlap count).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

from socialnav.config import ConfigError, check

HUMAN_MODELS = ("orca", "social_force", "linear")
ORCA_MODES = ("centralized", "decentralized")
VISIBILITIES = ("invisible", "visible")
KINEMATICS = ("holonomic", "unicycle")

# Bounds that keep one setting from exhausting the machine (docs/simulator.md, "Bounds"); checked
# when settings are built, i.e. before anything is allocated.
MAX_THREADS = 256  # native worker threads of one world
MAX_STEPS = 100_000  # samples of one episode: max(time_limit, continuation cap) / dt
MIN_DT = 1e-4  # [s]
MAX_OBSTACLE_VERTICES = 100_000  # the largest bound max_obstacle_vertices may be set to


@dataclass(frozen=True)
class OrcaSettings:
    """ORCA parameters CrowdSim passes to RVO2 (van den Berg et al., 2011)."""

    neighbor_dist: float = 10.0  # [m]
    max_neighbors: int = 10
    time_horizon: float = 5.0  # [s]
    time_horizon_obst: float = 5.0  # [s] for static obstacles (CrowdSim's timeHorizonObst)
    radius_margin: float = 0.01  # [m] CrowdSim inflates every radius by 1 cm
    safety_space: float = 0.0  # [m] extra inflation used by the humans

    def __post_init__(self) -> None:
        check(self.neighbor_dist > 0, "orca.neighbor_dist", self.neighbor_dist, "must be > 0")
        check(0 <= self.max_neighbors <= 64, "orca.max_neighbors", self.max_neighbors, "must be in [0, 64]")
        check(self.time_horizon > 0, "orca.time_horizon", self.time_horizon, "must be > 0")
        check(self.time_horizon_obst > 0, "orca.time_horizon_obst", self.time_horizon_obst, "must be > 0")
        check(self.radius_margin >= 0, "orca.radius_margin", self.radius_margin, "must be >= 0")
        check(self.safety_space >= 0, "orca.safety_space", self.safety_space, "must be >= 0")


@dataclass(frozen=True)
class SocialForceSettings:
    """Helbing & Molnár (1995) parameters (their published values)."""

    relaxation_time: float = 0.5  # tau [s]
    v0: float = 2.1  # repulsion strength V0 [m^2/s^2]
    sigma: float = 0.3  # repulsion range [m]
    step_time: float = 2.0  # delta t for the other's step [s]
    fov_half_angle: float = 100.0  # phi [deg]
    outside_fov_weight: float = 0.5  # c
    max_speed_factor: float = 1.3  # v_max / v_desired
    wall_u0: float = 10.0  # wall repulsion strength U0 [m^2/s^2] (Helbing & Molnár 1995)
    wall_r: float = 0.2  # wall repulsion range R [m] (Helbing & Molnár 1995)

    def __post_init__(self) -> None:
        check(self.wall_u0 >= 0, "social_force.wall_u0", self.wall_u0, "must be >= 0")
        for name in ("relaxation_time", "sigma", "step_time", "max_speed_factor", "wall_r"):
            value = getattr(self, name)
            check(value > 0, f"social_force.{name}", value, "must be > 0")
        check(self.v0 >= 0, "social_force.v0", self.v0, "must be >= 0")
        check(
            0 <= self.outside_fov_weight <= 1,
            "social_force.outside_fov_weight",
            self.outside_fov_weight,
            "must be in [0, 1]",
        )


@dataclass(frozen=True)
class RewardSettings:
    """CrowdSim's reward (recorded with every checkpoint)."""

    success_reward: float = 1.0
    collision_penalty: float = -0.25
    discomfort_dist: float = 0.2  # [m]
    discomfort_penalty_factor: float = 0.5
    #: Reward when the robot touches a static obstacle; None: the same as collision_penalty.
    obstacle_collision_penalty: float | None = None

    def __post_init__(self) -> None:
        check(self.discomfort_dist >= 0, "reward.discomfort_dist", self.discomfort_dist, "must be >= 0")

    @property
    def resolved_obstacle_collision_penalty(self) -> float:
        p = self.obstacle_collision_penalty
        return self.collision_penalty if p is None else p


@dataclass(frozen=True)
class WorldSettings:
    """Everything that defines the simulator's behaviour (not the scenario, not the policy)."""

    dt: float = 0.25  # [s]
    time_limit: float = 25.0  # [s]
    human_model: str = "orca"
    orca_mode: str = "centralized"
    visibility: str = "invisible"
    kinematics: str = "holonomic"
    rotation_limit: float = math.pi / 4  # [rad] per step, unicycle robot
    crowdsim_compat: bool = False
    reward: RewardSettings = field(default_factory=RewardSettings)
    orca: OrcaSettings = field(default_factory=OrcaSettings)
    social_force: SocialForceSettings = field(default_factory=SocialForceSettings)
    continue_after_success: bool = False  # keep simulating humans after the robot arrives (M_III)
    continuation_cap: float = 100.0  # [s] since the episode's start
    threads: int = 0  # native worker threads; 0 = all cores (at most 8)
    #: Bound on one episode's static-map vertices (a wall segment has 2); a larger map is refused.
    max_obstacle_vertices: int = 4096
    #: Touching a static obstacle ends the episode as a collision (else: the step's reward is
    #: reward.obstacle_collision_penalty and the episode goes on).
    obstacle_collision_ends: bool = True

    def __post_init__(self) -> None:
        check(math.isfinite(self.dt) and self.dt > 0, "dt", self.dt, "must be a finite number > 0")
        check(
            math.isfinite(self.time_limit) and self.time_limit > 0,
            "time_limit",
            self.time_limit,
            "must be a finite number > 0",
        )
        check(
            self.human_model in HUMAN_MODELS,
            "human_model",
            self.human_model,
            f"must be one of {', '.join(HUMAN_MODELS)}",
        )
        check(
            self.orca_mode in ORCA_MODES,
            "orca_mode",
            self.orca_mode,
            f"must be one of {', '.join(ORCA_MODES)}",
        )
        check(
            self.visibility in VISIBILITIES,
            "visibility",
            self.visibility,
            f"must be one of {', '.join(VISIBILITIES)}",
        )
        check(
            self.kinematics in KINEMATICS,
            "kinematics",
            self.kinematics,
            f"must be one of {', '.join(KINEMATICS)}",
        )
        check(0 < self.rotation_limit <= math.pi, "rotation_limit", self.rotation_limit, "must be in (0, pi]")
        check(
            math.isfinite(self.continuation_cap) and self.continuation_cap > 0,
            "continuation_cap",
            self.continuation_cap,
            "must be a finite number > 0",
        )
        check(self.dt >= MIN_DT, "dt", self.dt, f"must be >= {MIN_DT} s")
        steps = self.history_length() - 2
        if steps > MAX_STEPS:
            by_cap = self.continue_after_success and self.continuation_cap > self.time_limit
            name = "continuation_cap" if by_cap else "time_limit"
            value = getattr(self, name)
            raise ConfigError(
                f"{name} {value!r} with dt {self.dt!r} makes {steps} steps per episode, "
                f"more than the {MAX_STEPS} allowed (raise dt or lower {name})"
            )
        check(0 <= self.threads <= MAX_THREADS, "threads", self.threads, f"must be in [0, {MAX_THREADS}]")
        check(
            0 <= self.max_obstacle_vertices <= MAX_OBSTACLE_VERTICES,
            "max_obstacle_vertices",
            self.max_obstacle_vertices,
            f"must be in [0, {MAX_OBSTACLE_VERTICES}]",
        )

    @property
    def resolved_threads(self) -> int:
        return self.threads or max(1, min(os.cpu_count() or 1, 8))

    def history_length(self) -> int:
        """Samples to record per episode: the longest possible episode plus the initial state."""
        horizon = max(self.time_limit, self.continuation_cap if self.continue_after_success else 0.0)
        return int(math.ceil(horizon / self.dt)) + 2
