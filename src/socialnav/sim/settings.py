"""World settings: the simulator's semantics as data (docs/simulator.md).

Defaults are CrowdSim's. Every deviation from CrowdSim is a named field; ``crowdsim_compat``
restores CrowdSim's quirks (late timeout taking precedence, collision sweep with the humans'
previous velocities, no human-human overlap count).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import ClassVar

from socialnav.settings import Settings, setting

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
class OrcaSettings(Settings):
    """ORCA parameters CrowdSim passes to RVO2 (van den Berg et al., 2011)."""

    section: ClassVar[str] = "orca"

    neighbor_dist: float = setting(10.0, "agents farther than this are ignored", unit="m", gt=0)
    max_neighbors: int = setting(10, "nearest agents considered", ge=0, le=64)
    time_horizon: float = setting(5.0, "time horizon of the velocity obstacles of agents", unit="s", gt=0)
    time_horizon_obst: float = setting(
        5.0, "time horizon for static obstacles (CrowdSim's timeHorizonObst)", unit="s", gt=0
    )
    radius_margin: float = setting(0.01, "CrowdSim inflates every radius by 1 cm", unit="m", ge=0)
    safety_space: float = setting(0.0, "extra inflation used by the humans", unit="m", ge=0)


@dataclass(frozen=True)
class SocialForceSettings(Settings):
    """Helbing & Molnár (1995) parameters (their published values)."""

    section: ClassVar[str] = "social_force"

    relaxation_time: float = setting(0.5, "tau: relaxation time towards the desired velocity", unit="s", gt=0)
    v0: float = setting(2.1, "V0: repulsion strength", unit="m^2/s^2", ge=0)
    sigma: float = setting(0.3, "repulsion range", unit="m", gt=0)
    step_time: float = setting(2.0, "delta t for the other's step", unit="s", gt=0)
    fov_half_angle: float = setting(100.0, "phi: half angle of the field of view", unit="deg")
    outside_fov_weight: float = setting(0.5, "c: weight of forces from outside the field of view", ge=0, le=1)
    max_speed_factor: float = setting(1.3, "v_max / v_desired", gt=0)
    wall_u0: float = setting(
        10.0, "U0: wall repulsion strength (Helbing & Molnár 1995)", unit="m^2/s^2", ge=0
    )
    wall_r: float = setting(0.2, "R: wall repulsion range (Helbing & Molnár 1995)", unit="m", gt=0)


@dataclass(frozen=True)
class RewardSettings(Settings):
    """CrowdSim's reward (recorded with every checkpoint)."""

    section: ClassVar[str] = "reward"

    success_reward: float = setting(1.0, "reward for reaching the goal")
    collision_penalty: float = setting(-0.25, "reward for touching a human")
    discomfort_dist: float = setting(
        0.2, "clearance below which the discomfort penalty applies", unit="m", ge=0
    )
    discomfort_penalty_factor: float = setting(0.5, "penalty per metre inside discomfort_dist, per second")
    obstacle_collision_penalty: float | None = setting(
        None, "reward for touching a static obstacle; None: the same as collision_penalty"
    )

    @property
    def resolved_obstacle_collision_penalty(self) -> float:
        """The obstacle collision reward, ``collision_penalty`` when not set."""
        p = self.obstacle_collision_penalty
        return self.collision_penalty if p is None else p


@dataclass(frozen=True)
class WorldSettings(Settings):
    """Everything that defines the simulator's behaviour (not the scenario, not the policy)."""

    dt: float = setting(0.25, "time step", unit="s", gt=0, check=lambda dt: dt >= MIN_DT,
                        requirement=f"must be >= {MIN_DT} s")
    time_limit: float = setting(25.0, "episode time limit (a timeout after it)", unit="s", gt=0)
    human_model: str = setting("orca", "how the humans move", choices=HUMAN_MODELS)
    orca_mode: str = setting(
        "centralized", "ORCA humans solved in one simulator (CrowdSim) or each alone", choices=ORCA_MODES
    )
    visibility: str = setting(
        "invisible", "whether the humans see (react to) the robot", choices=VISIBILITIES
    )
    kinematics: str = setting("holonomic", "the robot's kinematics", choices=KINEMATICS)
    rotation_limit: float = setting(math.pi / 4, "heading change per step of a unicycle robot", unit="rad",
                                    gt=0, le=math.pi)
    crowdsim_compat: bool = setting(False, "restore CrowdSim's quirks (docs/simulator.md)")
    reward: RewardSettings = setting(default_factory=RewardSettings)
    orca: OrcaSettings = setting(default_factory=OrcaSettings)
    social_force: SocialForceSettings = setting(default_factory=SocialForceSettings)
    continue_after_success: bool = setting(
        False, "keep simulating the humans after the robot arrives (M_III)"
    )
    continuation_cap: float = setting(100.0, "end of that continuation, since the episode's start", unit="s",
                                      gt=0)
    threads: int = setting(0, "native worker threads; 0 = all cores (at most 8)", ge=0, le=MAX_THREADS)
    max_obstacle_vertices: int = setting(
        4096, "bound on one episode's static-map vertices (a wall segment has 2); a larger map is refused",
        ge=0, le=MAX_OBSTACLE_VERTICES,
    )
    obstacle_collision_ends: bool = setting(
        True, "touching a static obstacle ends the episode as a collision (else: the step's reward is "
        "reward.obstacle_collision_penalty and the episode goes on)"
    )

    def cross_check(self) -> None:
        """Refuses episodes longer than `MAX_STEPS` samples (before anything is allocated).

        Raises:
            ConfigError: naming time_limit or continuation_cap, whichever makes the episode long.
        """
        steps = self.history_length() - 2
        if steps > MAX_STEPS:
            by_cap = self.continue_after_success and self.continuation_cap > self.time_limit
            name = "continuation_cap" if by_cap else "time_limit"
            value = getattr(self, name)
            self.refuse(
                name,
                f"{value!r} with dt {self.dt!r} makes {steps} steps per episode, more than the "
                f"{MAX_STEPS} allowed (raise dt or lower {name})",
                got=False,
            )

    @property
    def resolved_threads(self) -> int:
        """Native worker threads: ``threads``, or all cores (at most 8) when 0."""
        return self.threads or max(1, min(os.cpu_count() or 1, 8))

    def history_length(self) -> int:
        """Samples to record per episode: the longest possible episode plus the initial state."""
        horizon = max(self.time_limit, self.continuation_cap if self.continue_after_success else 0.0)
        return int(math.ceil(horizon / self.dt)) + 2
