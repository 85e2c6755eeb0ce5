"""Named observation parts: the one definition of each piece of what a learner or a network observes.

An observation part is a registered class that declares, once:

- its ``name``, which compositions list (``ObservationSettings.parts`` for learners and the SB3 adapter,
  ``observation_parts`` of the Gymnasium envs, ``LearnedPolicySpec.observation_parts`` for the networks);
- its keys and their feature columns per frame (:attr:`ObservationPart.columns`: its feature widths);
- its Gymnasium space under a :class:`PartContext` (:meth:`ObservationPart.spaces`);
- how it is computed from the world's state of B episodes, batched, NumPy (:meth:`ObservationPart.compute`);
- for a set of agents the networks read as agents (the humans, the obstacle points), its rows in the
  world's human layout (:meth:`ObservationPart.agents`).

A consumer composes the parts it needs by name (:class:`ObservationComposition`), as Stable-Baselines3
gives each key of a dict observation its own feature extractor. The built-in parts
(:mod:`socialnav.sim.parts.builtin`): ``robot``, ``humans``, ``obstacle_points``, ``obstacle_edges``,
``lidar``, ``robot_twist``. A
part from outside the package is registered with :func:`register_observation_part` or through the entry
point group ``socialnav.observations`` (docs/extending.md).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Any, ClassVar

import numpy as np

from socialnav.sim.observation import Observation, ObstacleArrays
from socialnav.sim.obstacle_points import ObstaclePoints

__all__ = ["BOUND", "FRAMES", "NETWORK_PARTS", "SENSOR_KEYS", "ObservationPart", "PartContext", "PartInput",
           "sensor_arrays"]

#: Frames of a learner observation: the world's, or CrowdNav's agent-centric one (x-axis towards the goal).
FRAMES = ("world", "robot")
#: The bound of every Box an observation part declares (the raw env's, kept for every layout).
BOUND = 1e6
#: What the value networks and the PPO networks read by default: the robot's state, then the humans and
#: the obstacle points as agents (``LearnedPolicySpec.observation_parts``).
NETWORK_PARTS: tuple[str, ...] = ("robot", "humans", "obstacle_points")
#: The keys of a raw observation that hold the robot's sensor readings (carried to the parts as
#: ``PartInput.sensors`` by the learner wrappers and the SB3 adapter).
SENSOR_KEYS: tuple[str, ...] = ("lidar", "robot_twist")


def sensor_arrays(raw: Mapping[str, Any]) -> dict[str, Any]:
    """The sensor readings of a raw dict observation (its :data:`SENSOR_KEYS` it has)."""
    return {key: raw[key] for key in SENSOR_KEYS if key in raw}


@dataclass(frozen=True)
class PartContext:
    """The layout every part of one composition follows.

    Attributes:
        frame: "world" or "robot" (:data:`FRAMES`).
        length_scale: lengths [m] are divided by it.
        speed_scale: speeds [m/s] are divided by it.
        dtype: "float32" or "float64", of the feature arrays (masks are int8).
        human_slots: K, the human slots of the ``humans`` part.
        kinematics: "holonomic", "unicycle" or "diff_drive" (the robot frame's heading column).
        obstacle_points: the encoding of the ``obstacle_points`` part, None: the part adds nothing.
        max_edges: the edges of the ``obstacle_edges`` part (0: it adds nothing).
        raw: the raw Gymnasium env's layout: the world's own arrays in slot order (the humans not
            compacted, the scenario's own human count, possibly 0), world frame, SI units, float64.
        sensing: the world's :class:`~socialnav.sim.settings.SensingSettings` (its sensors' sizes: the
            ``lidar`` part's beams), None: the defaults (no lidar).
    """

    frame: str = "world"
    length_scale: float = 1.0
    speed_scale: float = 1.0
    dtype: str = "float32"
    human_slots: int = 1
    kinematics: str = "holonomic"
    obstacle_points: ObstaclePoints | None = None
    max_edges: int = 0
    raw: bool = False
    sensing: Any = None

    @classmethod
    def for_raw_env(cls, n_humans: int, kinematics: str, max_edges: int = 0,
                    sensing: Any = None) -> PartContext:
        """The raw env's layout (world frame, SI, float64, the scenario's own slots)."""
        return cls("world", 1.0, 1.0, "float64", int(n_humans), kinematics, None, int(max_edges), True,
                   sensing)

    @classmethod
    def for_networks(cls, obstacle_points: ObstaclePoints | None) -> PartContext:
        """The networks' layout: the world's rows, the obstacle points as agents of ``obstacle_points``."""
        return cls("world", 1.0, 1.0, "float64", 0, "holonomic", obstacle_points, 0, True)

    @cached_property
    def np_dtype(self) -> np.dtype:
        """The feature arrays' NumPy dtype."""
        return np.dtype(self.dtype)


class PartInput:
    """The world's state of B episodes that parts are computed from (what an :class:`Observation` holds).

    Args:
        robot: (B, 9) float64 robot rows (``ROBOT_COLUMNS["world"]``).
        humans: (B, N, 5) human rows (``HUMAN_COLUMNS["world"]``), zero where padded.
        human_mask: (B, N) bool, the real humans.
        maps: (B,) each episode's StaticMap or None (an open floor); None: ``default_map`` for all.
        obstacles: the flat maps (:class:`~socialnav.sim.observation.ObstacleArrays`) when the world gave
            them; built from ``maps`` where a part asks for them.
        default_map: the map of every episode when ``maps`` is None.
        observation: the world's :class:`~socialnav.sim.observation.Observation`, where the input is one
            (``time``, ``dt``, ``next_humans``, ... for parts that read more than the arrays).
        sensors: the robot's raw sensor arrays by key (``lidar``: (B, beams) ranges [m]; ``robot_twist``:
            (B, 2) a differential drive's (v, ω)), from the world's observation or a raw env's dict one.
    """

    def __init__(
        self,
        robot: np.ndarray,
        humans: np.ndarray,
        human_mask: np.ndarray,
        maps: Sequence[Any] | None = None,
        obstacles: ObstacleArrays | None = None,
        default_map: Any = None,
        observation: Observation | None = None,
        sensors: Mapping[str, np.ndarray] | None = None,
    ):
        self.robot = robot
        self.humans = humans
        self.human_mask = human_mask
        self._maps = maps
        self._obstacles = obstacles
        self._default_map = default_map or None
        self.observation = observation
        self.sensors: Mapping[str, np.ndarray] = sensors or {}
        self._fixed: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    @classmethod
    def from_observation(cls, obs: Observation) -> PartInput:
        """The input of a world's observation (its arrays as they are, its maps)."""
        walls = obs.obstacles
        maps = walls.maps if walls is not None else None
        sensors = {key: getattr(obs, key) for key in SENSOR_KEYS if getattr(obs, key) is not None}
        return cls(obs.robot, obs.humans, obs.human_mask, maps, walls, observation=obs, sensors=sensors)

    @classmethod
    def from_arrays(cls, robot: Any, humans: Any, mask: Any, maps: Sequence[Any] | None = None,
                    default_map: Any = None, sensors: Mapping[str, Any] | None = None) -> PartInput:
        """The input of raw arrays (a Gymnasium dict observation's rows), as float64 and bool."""
        return cls(np.asarray(robot, dtype=np.float64), np.asarray(humans, dtype=np.float64),
                   np.asarray(mask, dtype=bool), maps, default_map=default_map, sensors=sensors)

    @property
    def batch_size(self) -> int:
        """The number of episodes B."""
        return self.robot.shape[0]

    @property
    def maps(self) -> Sequence[Any]:
        """(B,) each episode's static map or None."""
        if self._maps is not None:
            return self._maps
        return (self._default_map,) * self.batch_size

    @property
    def obstacles(self) -> ObstacleArrays | None:
        """The flat maps of the B episodes (None: every episode is an open floor)."""
        if self._obstacles is None and any(self.maps):
            self._obstacles = ObstacleArrays.from_maps(self.maps)
        return self._obstacles

    @cached_property
    def goal_frame(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(B,) each robot's heading towards its goal rot = atan2(gy - py, gx - px), cos rot and sin rot."""
        r = self.robot
        rot = np.arctan2(r[:, 6] - r[:, 1], r[:, 5] - r[:, 0])
        return rot, np.cos(rot), np.sin(rot)

    def fixed_humans(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """(B, k, 5) human rows and (B, k) mask: real humans first in slot order, the nearest k where more."""
        if k not in self._fixed:
            self._fixed[k] = _fixed_count(
                self.robot, np.asarray(self.humans, np.float64), np.asarray(self.human_mask, bool), k
            )
        return self._fixed[k]


def _fixed_count(robot: np.ndarray, humans: np.ndarray, mask: np.ndarray, k: int):
    """(B, K, 5) humans and (B, K) mask: real humans first in slot order, the nearest k where more."""
    b, n = mask.shape
    keep = mask
    if mask.sum(axis=1).max(initial=0) > k:
        dist = np.where(
            mask, np.hypot(humans[..., 0] - robot[:, None, 0], humans[..., 1] - robot[:, None, 1]), np.inf
        )
        rank = np.argsort(np.argsort(dist, axis=1, kind="stable"), axis=1, kind="stable")
        keep = mask & (rank < k)
    order = np.argsort(~keep, axis=1, kind="stable")[:, : min(n, k)]  # kept slots first, in slot order
    out = np.zeros((b, k, humans.shape[2]))
    out_mask = np.zeros((b, k), dtype=bool)
    rows = np.arange(b)[:, None]
    out[:, : order.shape[1]] = humans[rows, order]
    out_mask[:, : order.shape[1]] = keep[rows, order]
    return out, out_mask


class ObservationPart:
    """One named piece of an observation (subclass it and register it; the module docstring says how).

    A subclass sets :attr:`name`, :attr:`description` and :attr:`columns` and implements :meth:`compute`;
    the default :meth:`spaces` declares one Box of shape ``(width,)`` per key of :attr:`columns`. A set
    of agents (a variable number of rows with a mask) overrides :meth:`spaces`, and where the networks
    should read it as agents, :meth:`agents` (and :attr:`static` when they never move).
    """

    #: The name compositions list (unique among the registered parts).
    name: ClassVar[str] = ""
    #: One line for ``socialnav list``.
    description: ClassVar[str] = ""
    #: Feature key → frame → column names: the feature widths, declared once. A part offers the frames
    #: every one of its keys lists.
    columns: ClassVar[Mapping[str, Mapping[str, tuple[str, ...]]]] = {}
    #: Its agents never move (the lookahead keeps them where they are; they come after moving agents).
    static: ClassVar[bool] = False
    #: It reads the walls (``PartInput.maps`` or ``obstacles``), so the learner wrappers and the SB3
    #: adapter hand it each episode's map. True unless a part declares otherwise: a part that never reads
    #: them may say so, which spares a vector env of env copies a query of every copy's map per step.
    reads_maps: ClassVar[bool] = True
    #: Its keys show the walls without reading the maps (a sensor's readings, as the lidar's): with a part
    #: that reads the maps, what tells a learner wrapper that a policy trained on the layout sees the walls.
    sees_walls: ClassVar[bool] = False
    #: The raw observation's sensor keys it reads from ``PartInput.sensors`` (:data:`SENSOR_KEYS`): a
    #: learner wrapper refuses, when it is built, a raw env whose observation lacks one.
    sensor_keys: ClassVar[tuple[str, ...]] = ()

    def frames(self) -> tuple[str, ...]:
        """The frames this part can be laid out in."""
        frames = [set(per_frame) for per_frame in self.columns.values()]
        common = set.intersection(*frames) if frames else set(FRAMES)
        return tuple(f for f in FRAMES if f in common)

    def width(self, key: str, frame: str = "world") -> int:
        """The feature width of ``key`` (its last axis) in ``frame``."""
        return len(self.columns[key][frame])

    def spaces(self, ctx: PartContext) -> dict[str, Any]:
        """One episode's keys and their Gymnasium spaces under ``ctx`` (empty: the part adds nothing)."""
        from gymnasium import spaces

        return {
            key: spaces.Box(-BOUND, BOUND, shape=(self.width(key, ctx.frame),), dtype=ctx.np_dtype)
            for key in self.columns
        }

    def compute(self, data: PartInput, ctx: PartContext) -> dict[str, np.ndarray]:
        """The part's arrays of B episodes, (B, …) per key of :meth:`spaces`, in ``ctx``'s layout.

        Raises:
            NotImplementedError: A subclass must implement it.
        """
        raise NotImplementedError(f"observation part {self.name!r} does not implement compute()")

    @property
    def is_agent_set(self) -> bool:
        """Whether the networks can read this part as agents (its class implements :meth:`agents`)."""
        return type(self).agents is not ObservationPart.agents

    def agents(self, data: PartInput, ctx: PartContext) -> tuple[np.ndarray, np.ndarray] | None:
        """The part as agents the networks read like humans: (B, K, 5) world rows and (B, K) bool mask.

        None (the default): the part is not a set of agents.
        """
        return None

    def check_context(self, ctx: PartContext) -> None:
        """Refuses a layout this part cannot give (a frame it does not declare).

        Raises:
            ValueError: Naming the part, the frame and the ones it offers.
        """
        if ctx.frame not in self.frames():
            raise ValueError(f"observation part {self.name!r} has no {ctx.frame!r} frame (it offers "
                             f"{', '.join(self.frames()) or 'none'})")
