"""World settings: the simulator's semantics as data (docs/simulator.md).

Defaults are CrowdSim's. Every deviation from CrowdSim is a named field; ``crowdsim_compat``
restores CrowdSim's quirks (late timeout taking precedence, collision sweep with the humans'
previous velocities, no human-human overlap count).
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from socialnav.settings import Settings, setting
from socialnav.settings.validation import type_hints
from socialnav.sim.behaviours import HUMAN_MODELS, human_behaviour, native_settings

ORCA_MODES = ("centralized", "decentralized")
VISIBILITIES = ("invisible", "visible")
KINEMATICS = ("holonomic", "unicycle", "diff_drive")
#: The kinematics whose actions are (v, dθ) and whose robot has a heading (the rest: holonomic (vx, vy)).
HEADED_KINEMATICS = ("unicycle", "diff_drive")
HUMAN_ROUTES = ("none", "shortest")

# Bounds that keep one setting from exhausting the machine (docs/simulator.md, "Bounds"); checked
# when settings are built, i.e. before anything is allocated.
MAX_THREADS = 256  # native worker threads of one world
MAX_STEPS = 100_000  # samples of one episode: max(time_limit, continuation cap) / dt
MIN_DT = 1e-4  # [s]
MAX_OBSTACLE_VERTICES = 100_000  # the largest bound max_obstacle_vertices may be set to


#: The native behaviours' parameter sections, built from their declarations in the core
#: (cpp/behaviours/; socialnav.sim.behaviours): ORCA (van den Berg et al., 2011) as CrowdSim passes it to
#: RVO2, and Helbing & Molnár's (1995) social force with their published values.
#: (Type checkers see them as variables: annotations naming them are marked ``type: ignore[valid-type]``.)
OrcaSettings = native_settings("orca")
SocialForceSettings = native_settings("social_force")


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


#: The lidar's settings (``SensingSettings``), which a policy may bring to its world (``with_sensors``).
LIDAR_FIELDS = ("lidar_beams", "lidar_fov", "lidar_range", "lidar_noise")
#: Those its scan's layout and scale depend on: brought at their defaults where a policy names none.
LIDAR_GEOMETRY = ("lidar_beams", "lidar_fov", "lidar_range")


@dataclass(frozen=True)
class SensingSettings(Settings):
    """What the robot perceives (docs/perception.md); the defaults are the world's exact state.

    Detections (the ``humans`` the robot observes) and the lidar are the robot's view only: collisions,
    rewards and every metric read the ground truth. Range and field of view apply to a human's centre
    (CrowdNav++'s rule), occlusion to its whole disc (hidden when no point of it is in sight).
    """

    section: ClassVar[str] = "sensing"

    range: float | None = setting(
        None, "humans whose centre is farther are not detected; None: no limit", unit="m", gt=0
    )
    fov: float = setting(
        2 * math.pi, "detection sector about the robot's heading (a holonomic robot: its direction of "
        "travel, towards its goal while it stands)", unit="rad", gt=0, le=2 * math.pi,
    )
    occlusion_walls: bool = setting(False, "a human no point of whose disc is in sight past the walls is "
                                    "not detected")
    occlusion_humans: bool = setting(False, "a human hidden behind other humans' discs is not detected")
    position_noise: float = setting(0.0, "std of the Gaussian noise on each detected position coordinate",
                                    unit="m", ge=0, le=100.0)
    velocity_noise: float = setting(0.0, "std of the Gaussian noise on each detected velocity coordinate",
                                    unit="m/s", ge=0, le=100.0)
    dropout: float = setting(0.0, "probability that a detectable human is missed in a step", ge=0, le=1)
    latency: int = setting(0, "the detections are of the world this many steps ago", ge=0, le=1000)
    lidar_beams: int = setting(0, "beams of the robot's 2-D lidar (the observation part lidar); 0: none",
                               ge=0, le=100_000)
    lidar_fov: float = setting(2 * math.pi, "the lidar's sector about the robot's heading", unit="rad", gt=0,
                               le=2 * math.pi)
    lidar_range: float = setting(10.0, "the lidar's maximum range (a beam that hits nothing reads it)",
                                 unit="m", gt=0, le=1000.0)
    lidar_noise: float = setting(0.0, "std of the Gaussian noise on each lidar return", unit="m", ge=0,
                                 le=100.0)

    @property
    def exact(self) -> bool:
        """Whether the robot detects every human exactly (the lidar aside)."""
        return (self.range is None and self.fov >= 2 * math.pi and not self.occlusion_walls
                and not self.occlusion_humans and self.position_noise == 0 and self.velocity_noise == 0
                and self.dropout == 0 and self.latency == 0)

    @property
    def is_default(self) -> bool:
        """Whether these are the defaults (exact detections, no lidar): the world then senses nothing."""
        return self.exact and self.lidar_beams == 0


@dataclass(frozen=True)
class DiffDriveSettings(Settings):
    """The differential-drive robot's limits (``kinematics: diff_drive``; docs/kinematics.md).

    Its actions are the unicycle's (v, dθ): v within [-max_reverse_speed, v_pref], dθ/dt within
    ±rotation_limit/dt. Each step the robot reaches the commanded (v, ω) from the last step's as far as the
    acceleration limits allow (a dynamic window), then drives that arc exactly. The defaults are ROS 2
    Nav2's DWB controller defaults (acc_lim_x 2.5 m/s², acc_lim_theta 3.2 rad/s², no reversing).
    """

    section: ClassVar[str] = "diff_drive"

    max_linear_acceleration: float = setting(2.5, "largest change of the forward speed", unit="m/s²", gt=0,
                                             le=1000.0)
    max_angular_acceleration: float = setting(3.2, "largest change of the turn rate", unit="rad/s²", gt=0,
                                              le=1000.0)
    max_reverse_speed: float = setting(0.0, "how fast the robot may back up; 0: never", unit="m/s", ge=0,
                                       le=100.0)


@dataclass(frozen=True)
class WorldSettings(Settings):
    """Everything that defines the simulator's behaviour (not the scenario, not the policy)."""

    dt: float = setting(0.25, "time step", unit="s", gt=0, check=lambda dt: dt >= MIN_DT,
                        requirement=f"must be >= {MIN_DT} s")
    time_limit: float = setting(25.0, "episode time limit (a timeout after it)", unit="s", gt=0)
    human_model: str = setting(
        "orca", "how the humans move: a registered pedestrian behaviour (socialnav list)",
        choices=HUMAN_MODELS,
    )
    orca_mode: str = setting(
        "centralized", "ORCA humans solved in one simulator (CrowdSim) or each alone", choices=ORCA_MODES
    )
    visibility: str = setting(
        "invisible", "whether the humans see (react to) the robot", choices=VISIBILITIES
    )
    kinematics: str = setting("holonomic", "the robot's kinematics", choices=KINEMATICS)
    rotation_limit: float = setting(math.pi / 4, "heading change per step of a unicycle or diff_drive robot",
                                    unit="rad",
                                    gt=0, le=math.pi)
    crowdsim_compat: bool = setting(False, "restore CrowdSim's quirks (docs/simulator.md)")
    reward: RewardSettings = setting(default_factory=RewardSettings)
    orca: OrcaSettings = setting(default_factory=OrcaSettings)  # type: ignore[valid-type]
    social_force: SocialForceSettings = setting(default_factory=SocialForceSettings)  # type: ignore[valid-type]
    human_params: dict[str, Any] | None = setting(
        None, "parameters of a human_model without a section of its own here (one registered outside "
        "socialnav): a mapping of some of them, the rest default; left out of records while None",
        record_default=False,
    )
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
    human_routes: str = setting(
        "none", "among static obstacles, the humans follow the shortest route to their goal around the walls "
        "(shortest; docs/routes.md) or head straight for it (none); no effect on an open floor; left out of "
        "records while none", choices=HUMAN_ROUTES, record_default=False,
    )
    route_clearance: float = setting(
        0.2, "distance beyond their radius that routed humans keep from walls where the passage allows; left "
        "out of records while 0.2", unit="m", ge=0, le=10.0, record_default=False,
    )
    sensing: SensingSettings = setting(
        default_factory=SensingSettings, record_default=False,
    )
    diff_drive: DiffDriveSettings = setting(default_factory=DiffDriveSettings, record_default=False)

    def recorded_at_default(self) -> tuple[str, ...]:
        """Fields recorded even at their default: a differential drive's limits, which define its robot."""
        return ("diff_drive",) if self.kinematics == "diff_drive" else ()

    def with_sensors(self, sensors: Mapping[str, Any] | None) -> WorldSettings:
        """These settings with the lidar a policy brings (``sensing``'s lidar fields, e.g. its beams).

        A policy that reads a lidar the protocol's world lacks (``lidar_ppo``'s, an SB3 model's, or a policy
        of one's own declaring ``sensors = {"lidar_beams": 90}``) acts in the world with it added; the
        detections, the humans and every metric are unchanged (docs/perception.md). The lidar it brings has
        the beams, sector and range it names, the defaults for those it does not (a full circle, 10 m), and
        the world's noise unless it names one.

        Raises:
            ValueError: A key that is not a lidar setting (the detections are the preset's), or a lidar the
                world already has in another form: one with beams, or a lidar field the world sets to
                other than its default (e.g. a 1-rad ``lidar_fov`` for a policy trained on the full circle).
        """
        if not sensors:
            return self
        current, default = self.sensing, SensingSettings()
        other = sorted(k for k in sensors if k not in LIDAR_FIELDS)
        if other:
            raise ValueError(
                f"a policy's sensors name lidar settings only ({', '.join(LIDAR_FIELDS)}), not "
                f"{', '.join(other)}: what the robot detects is the preset's world.sensing "
                "(docs/perception.md)"
            )
        brought = {k: sensors.get(k, getattr(default, k)) for k in LIDAR_GEOMETRY}
        if "lidar_noise" in sensors:
            brought["lidar_noise"] = sensors["lidar_noise"]
        # the world's lidar fields are its own where it has a lidar, or where it sets them
        clash = [k for k, v in brought.items() if getattr(current, k) != v
                 and (current.lidar_beams or getattr(current, k) != getattr(default, k))]
        if clash:
            shown = ", ".join(f"{k} {getattr(current, k)!r} (world) vs {brought[k]!r}" for k in clash)
            raise ValueError(f"the policy brings a lidar the world already has in another form: {shown}")
        return dataclasses.replace(self, sensing=dataclasses.replace(current, **brought))

    def cross_check(self) -> None:
        """Resolves ``human_params``; refuses episodes longer than `MAX_STEPS` samples.

        Both before anything is allocated.

        Raises:
            ConfigError: naming human_params (a parameter of the behaviour, or parameters given to one
                whose parameters live elsewhere), or time_limit or continuation_cap, whichever makes the
                episode long.
        """
        self._resolve_human_params()
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

    def _resolve_human_params(self) -> None:
        """Stores ``human_params`` as every parameter of ``human_model`` (None where it has a section)."""
        info = human_behaviour(self.human_model)
        given = self.human_params
        names = [p.name for p in info.parameters.parameters()]
        if self.human_model in self._sections() or not names:
            if given:
                where = f"world.{self.human_model}" if names else "nowhere: it has none"
                self.refuse("human_params", f"must be empty for human_model {self.human_model!r} (its "
                            f"parameters are set in {where})")
            object.__setattr__(self, "human_params", None)
            return
        if given is not None and not isinstance(given, Mapping):
            self.refuse("human_params", f"must be a mapping of the parameters of {self.human_model!r} "
                        f"({', '.join(names)})")
        values = info.parameters.from_dict(given, section="human_params")
        object.__setattr__(self, "human_params", values.to_dict())

    @classmethod
    def _sections(cls) -> frozenset[str]:
        """The behaviours whose parameters are a section of their own: a field named after them."""
        hints = type_hints(cls)
        return frozenset(f.name for f in dataclasses.fields(cls)
                         if f.name in HUMAN_MODELS and hints[f.name] is human_behaviour(f.name).parameters)

    def human_parameters(self) -> Settings:
        """The parameters of ``human_model``: its section, or ``human_params`` as its settings class.

        Returns:
            An instance of the behaviour's settings class (for a Python behaviour: the behaviour itself).
        """
        cls = human_behaviour(self.human_model).parameters
        if self.human_model in self._sections():
            return getattr(self, self.human_model)
        return cls(**(self.human_params or {}))

    @property
    def resolved_threads(self) -> int:
        """Native worker threads: ``threads``, or all cores (at most 8) when 0."""
        return self.threads or max(1, min(os.cpu_count() or 1, 8))

    def history_length(self) -> int:
        """Samples to record per episode: the longest possible episode plus the initial state."""
        horizon = max(self.time_limit, self.continuation_cap if self.continue_after_success else 0.0)
        return int(math.ceil(horizon / self.dt)) + 2
