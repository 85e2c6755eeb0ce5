"""Observations a learner can use.

One transformation shared by the single env, the vector env, the SB3 adapter and the ``sb3:`` evaluation
policy (docs/train_your_own.md): the composition of the named observation parts its settings list
(``parts``; :mod:`socialnav.sim.parts`), each computed by its part, in the layout the settings give.

The raw observation (:mod:`socialnav.sim.observation`) is world-frame float64 with the scenario's own
human count. :class:`ObservationSettings` names what a learner usually wants instead:

- ``frame="robot"``: CrowdNav's agent-centric frame (Chen et al., "Crowd-Robot Interaction", ICRA
  2019; the ``rotate`` the value networks use, socialnav.policies.learned.state): x-axis from the robot
  towards its goal. Holonomic actions are then given in that frame too and rotated back to the world
  before they reach the simulator (a policy that sees no world heading could not aim a world-frame
  velocity); unicycle actions (v, dθ) are body-frame already.
- ``max_humans``: a fixed human count. Real humans come first in slot order, the rest are zero rows
  with mask 0; where an episode has more humans than that, the nearest ``max_humans`` are kept (in slot
  order). A model trained on the 5-human mix so sees 1 human and 4 padded slots on a single-human sweep.
- ``length_scale`` / ``speed_scale``: lengths [m] and speeds [m/s] are divided by them (1 = SI units).
- ``dtype``: of ``robot`` and ``humans`` (float32 by default: what networks take).

Layouts (B leading rows in a batch; K = max_humans):

=========  =====  ==========================================================================
frame      key    columns
=========  =====  ==========================================================================
world      robot  (9,)  px, py, vx, vy, radius, gx, gy, v_pref, theta
world      humans (K, 5) px, py, vx, vy, radius
robot      robot  (6,)  dg, v_pref, theta', radius, vx', vy'   (theta' = theta - rot, unicycle; 0 holonomic)
robot      humans (K, 7) px', py', vx', vy', radius, da, radius + robot radius
both       human_mask (K,) int8, 1 for a real human
=========  =====  ==========================================================================

Lengths (positions, radii, dg, da) are in units of ``length_scale``, speeds (velocities, v_pref) in
units of ``speed_scale``; angles in radians. rot = atan2(gy - py, gx - px).

Obstacles (``obstacle_points`` = P > 0; 0, the default, adds no key): the P points of the obstacle
outlines nearest to the robot within ``obstacle_range``, sampled every ``obstacle_spacing`` at most
along each edge with every vertex included (:mod:`socialnav.sim.obstacle_points`, the encoding the
value networks use), nearest first, zero rows where padded:

=========  ===================  ===========================================================
frame      key                  columns
=========  ===================  ===========================================================
world      obstacle_points      (P, 2) px, py
robot      obstacle_points      (P, 3) px', py', distance to the robot's centre
both       obstacle_point_mask  (P,) int8, 1 for a real point
=========  ===================  ===========================================================

in units of ``length_scale``, dtype ``dtype``.

Parts (``parts``): the named observation parts, in order; the default ``("robot", "humans",
"obstacle_points")`` gives the keys above. A part registered from outside the package
(:func:`socialnav.sim.register_observation_part`) adds its own keys where it is listed (docs/extending.md).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from socialnav.maps.static_map import StaticMap
from socialnav.settings import check
from socialnav.sim.observation import HUMAN_COLUMNS, ROBOT_COLUMNS
from socialnav.sim.obstacle_points import ObstaclePoints
from socialnav.sim.parts.base import FRAMES, PartContext, PartInput
from socialnav.sim.parts.builtin import OBSTACLE_COLUMNS
from socialnav.sim.parts.composition import ObservationComposition, check_part_names

__all__ = [
    "DEFAULT_PARTS",
    "FRAMES",
    "HUMAN_COLUMNS",
    "OBSTACLE_COLUMNS",
    "ROBOT_COLUMNS",
    "ObservationSettings",
    "ObservationTransform",
]

DTYPES = ("float32", "float64")
#: A learner's observation parts unless its settings name others (the keys of every model saved so far).
DEFAULT_PARTS: tuple[str, ...] = ("robot", "humans", "obstacle_points")


@dataclass(frozen=True)
class ObservationSettings:
    """How raw observations are turned into a learner's (see the module docstring).

    ``max_humans=None`` means the env's own human count; the adapters resolve it when built, and the
    resolved number is what a saved model records. ``parts`` names the observation parts, in order
    (:mod:`socialnav.sim.parts`); :meth:`to_dict` leaves it out where it is the default, so that the
    records of models saved before parts existed are unchanged.
    """

    frame: str = "world"
    max_humans: int | None = None
    length_scale: float = 1.0  # [m]
    speed_scale: float = 1.0  # [m/s]
    dtype: str = "float32"
    obstacle_points: int = 0  # P; 0: no obstacle keys (the layout of open-floor models)
    obstacle_spacing: float = 0.5  # [m]
    obstacle_range: float = 4.0  # [m]
    parts: tuple[str, ...] = DEFAULT_PARTS

    def __post_init__(self) -> None:
        check(self.frame in FRAMES, "observation.frame", self.frame, f"must be one of {', '.join(FRAMES)}")
        check(
            self.max_humans is None
            or (isinstance(self.max_humans, int) and not isinstance(self.max_humans, bool)
                and self.max_humans >= 1),
            "observation.max_humans",
            self.max_humans,
            "must be an integer >= 1 or None",
        )
        for name in ("length_scale", "speed_scale", "obstacle_spacing", "obstacle_range"):
            value = getattr(self, name)
            check(
                isinstance(value, int | float) and math.isfinite(value) and value > 0,
                f"observation.{name}",
                value,
                "must be a finite number > 0",
            )
        check(self.dtype in DTYPES, "observation.dtype", self.dtype, f"must be one of {', '.join(DTYPES)}")
        check(
            isinstance(self.obstacle_points, int) and not isinstance(self.obstacle_points, bool)
            and self.obstacle_points >= 0,
            "observation.obstacle_points",
            self.obstacle_points,
            "must be an integer >= 0",
        )
        object.__setattr__(self, "parts", check_part_names(self.parts, "observation.parts", check))
        check(bool(self.parts), "observation.parts", list(self.parts), "must name at least one part")
        check(
            not self.obstacle_points or "obstacle_points" in self.parts,
            "observation.obstacle_points",
            self.obstacle_points,
            f"asks for obstacle points, but observation.parts {list(self.parts)} lack the part "
            "'obstacle_points' that gives them (add it, or set obstacle_points to 0)",
        )

    @property
    def obstacle_encoding(self) -> ObstaclePoints | None:
        """The point encoding of the obstacle keys, None without them."""
        if not self.obstacle_points:
            return None
        return ObstaclePoints(
            self.obstacle_points, float(self.obstacle_spacing), float(self.obstacle_range), 0.0
        )

    def context(self, human_slots: int, kinematics: str, sensing: Any = None) -> PartContext:
        """The parts' layout with ``human_slots`` human slots (``sensing``: the world's sensors)."""
        return PartContext(
            frame=self.frame,
            length_scale=self.length_scale,
            speed_scale=self.speed_scale,
            dtype=self.dtype,
            human_slots=int(human_slots),
            kinematics=kinematics,
            obstacle_points=self.obstacle_encoding,
            sensing=sensing,
        )

    def to_dict(self) -> dict[str, Any]:
        """The settings as a plain dict (the training record's; ``parts`` only where not the default)."""
        out = dataclasses.asdict(self)
        if self.parts == DEFAULT_PARTS:
            del out["parts"]
        else:
            out["parts"] = list(self.parts)
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any] | None) -> ObservationSettings:
        """Settings from a dict such as :meth:`to_dict` writes (None: the defaults).

        Raises:
            ConfigError: An unknown key or a bad value, named.
        """
        from socialnav.settings import from_dict

        return from_dict(cls, data or {}, "observation")


class ObservationTransform:
    """Raw batched arrays -> the learner's dict (and, for ``frame="robot"``, actions back to the world).

    The dict is the composition of the settings' parts (:class:`~socialnav.sim.parts.ObservationComposition`).

    Args:
        settings: The transformation.
        n_humans: The env's human slot count (resolves ``max_humans=None``).
        kinematics: "holonomic" or "unicycle" (decides theta' and whether actions are rotated).
        action_set: "continuous" or "discrete"; a discrete holonomic action is a world-frame heading,
            which a robot-frame policy cannot aim, so that combination is refused.
        static_map: the env's map (one for every episode), used when a call passes no ``maps``.
    """

    def __init__(
        self,
        settings: ObservationSettings,
        n_humans: int,
        kinematics: str,
        action_set: str = "continuous",
        static_map: StaticMap | None = None,
        sensing: Any = None,
    ):
        if settings.max_humans is None:  # a crowd-free env keeps one (padded) slot: networks need inputs
            settings = dataclasses.replace(settings, max_humans=max(int(n_humans), 1))
        if settings.frame == "robot" and kinematics == "holonomic" and action_set == "discrete":
            raise ValueError(
                "observation frame 'robot' with discrete holonomic actions: CrowdSim's 81 actions are "
                "world-frame headings, which a policy that sees the robot frame cannot aim; use "
                "action_set='continuous' (rotated back to the world) or frame='world'"
            )
        self.settings = settings
        self.kinematics = kinematics
        self.rotates_actions = (
            settings.frame == "robot" and kinematics == "holonomic" and action_set != "discrete"
        )
        self.dtype = np.dtype(settings.dtype)
        self.static_map = static_map or None
        self.composition = ObservationComposition(
            settings.parts, settings.context(int(settings.max_humans), kinematics, sensing)
        )

    @property
    def max_humans(self) -> int:
        """The human slots of the transformed observation."""
        return int(self.settings.max_humans)

    def single_space(self) -> Any:
        """The space of one episode's transformed observation (a ``gymnasium.spaces.Dict``)."""
        return self.composition.single_space()

    def __call__(
        self, robot: np.ndarray, humans: np.ndarray, mask: np.ndarray, maps: Any = None,
        sensors: Mapping[str, np.ndarray] | None = None,
    ) -> dict[str, np.ndarray]:
        """``robot`` (B, 9), ``humans`` (B, N, 5), ``mask`` (B, N) -> the learner's (B, …) arrays.

        ``maps``: each episode's :class:`~socialnav.maps.static_map.StaticMap` or None, (B,); None: the
        transform's own ``static_map`` for every episode (read by parts that need the walls).
        ``sensors``: the raw observation's sensor readings (``sensor_arrays``: the lidar).
        """
        return self.composition(PartInput.from_arrays(robot, humans, mask, maps, self.static_map, sensors))

    def actions_to_world(self, actions: np.ndarray, robot: np.ndarray) -> np.ndarray:
        """The simulator's actions for ``actions`` chosen on the observation of raw ``robot`` (B, 9).

        Robot-frame holonomic velocities are rotated by rot (the robot-to-goal heading); anything else
        passes unchanged.
        """
        if not self.rotates_actions:
            return actions
        a, c, s = _actions_and_goal_heading(actions, robot)
        return np.stack([a[:, 0] * c - a[:, 1] * s, a[:, 0] * s + a[:, 1] * c], axis=1)

    def actions_from_world(self, actions: np.ndarray, robot: np.ndarray) -> np.ndarray:
        """Convert a world-frame action to the learner's action; the inverse of :meth:`actions_to_world`.

        Used e.g. for a teacher's actions in imitation.
        """
        if not self.rotates_actions:
            return actions
        a, c, s = _actions_and_goal_heading(actions, robot)
        return np.stack([a[:, 0] * c + a[:, 1] * s, a[:, 1] * c - a[:, 0] * s], axis=1)


def _actions_and_goal_heading(actions: np.ndarray, robot: np.ndarray) -> tuple[np.ndarray, ...]:
    """(B, 2) actions and the cosine and sine of each robot's heading towards its goal."""
    a = np.asarray(actions, dtype=np.float64).reshape(-1, 2)
    robot = np.asarray(robot, dtype=np.float64).reshape(-1, len(ROBOT_COLUMNS["world"]))
    rot = np.arctan2(robot[:, 6] - robot[:, 1], robot[:, 5] - robot[:, 0])
    return a, np.cos(rot), np.sin(rot)
