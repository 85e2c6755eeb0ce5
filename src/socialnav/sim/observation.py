"""Batched observations: what a policy sees of the world (CrowdSim's full information)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from socialnav.maps.static_map import StaticMap

#: The one definition of the robot's and the humans' feature columns, hence of their widths. ``world``:
#: the world's state rows (``Observation.robot`` (B, 9), ``Observation.humans`` (B, N, 5), what the
#: networks' lookahead propagates); ``robot``: CrowdNav's agent-centric frame (x-axis from the robot
#: towards its goal; the learner observations' ``frame="robot"``, and the value networks' joint state is
#: the robot part (6) followed by one human's part (7)). The observation parts (socialnav.sim.parts),
#: the learner observations, the Gymnasium envs and the networks all read these.
ROBOT_COLUMNS: dict[str, tuple[str, ...]] = {
    "world": ("px", "py", "vx", "vy", "radius", "gx", "gy", "v_pref", "theta"),
    "robot": ("dg", "v_pref", "theta", "radius", "vx", "vy"),
}
HUMAN_COLUMNS: dict[str, tuple[str, ...]] = {
    "world": ("px", "py", "vx", "vy", "radius"),
    "robot": ("px", "py", "vx", "vy", "radius", "da", "radius_sum"),
}
ROBOT_DIM = len(ROBOT_COLUMNS["world"])
HUMAN_DIM = len(HUMAN_COLUMNS["world"])
(ROBOT_PX, ROBOT_PY, ROBOT_VX, ROBOT_VY, ROBOT_RADIUS, ROBOT_GX, ROBOT_GY, ROBOT_VPREF,
 ROBOT_THETA) = range(ROBOT_DIM)
HUMAN_PX, HUMAN_PY, HUMAN_VX, HUMAN_VY, HUMAN_RADIUS = range(HUMAN_DIM)


@dataclass(frozen=True, eq=False)
class ObstacleArrays:
    """The static maps of B episodes, flat for the native policies (``None`` rows are open floors).

    Attributes:
        maps: (B,) the episodes' :class:`~socialnav.maps.static_map.StaticMap` or None.
        vertices: (V, 2) every polygon's vertices [m], episode after episode.
        polygon_offsets: (P + 1,) int64; polygon p is
            ``vertices[polygon_offsets[p]:polygon_offsets[p + 1]]``.
        episode_polygons: (B + 1,) int64; episode b has the polygons
            ``episode_polygons[b]:episode_polygons[b + 1]``.
    """

    maps: tuple
    vertices: np.ndarray
    polygon_offsets: np.ndarray
    episode_polygons: np.ndarray

    @classmethod
    def from_maps(cls, maps: Sequence[StaticMap | None]) -> ObstacleArrays | None:
        """The flat form of ``maps``, or None when every episode is an open floor."""
        maps = tuple(m if m else None for m in maps)
        if all(m is None for m in maps):
            return None
        polygons = [p for m in maps if m is not None for p in m.polygons]
        counts = np.array([len(p) for p in polygons], dtype=np.int64)
        per_episode = np.array([0 if m is None else len(m) for m in maps], dtype=np.int64)
        return cls(
            maps,
            np.ascontiguousarray(np.concatenate(polygons), dtype=np.float64),
            np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
            np.concatenate([[0], np.cumsum(per_episode)]).astype(np.int64),
        )

    @cached_property
    def native(self):
        """The maps prepared once for the native robot policies (``_core.PreparedObstacleBatch``)."""
        from socialnav import _core

        return _core.PreparedObstacleBatch(self.vertices, self.polygon_offsets, self.episode_polygons)

    def padded_edges(self, max_edges: int) -> tuple[np.ndarray, np.ndarray]:
        """Every episode's obstacle edges as a fixed-size, zero-padded list.

        Segments (B, max_edges, 4) of (x1, y1, x2, y2) [m] (a wall is one edge, a k-gon k edges, in map
        order), zero-padded, and their mask (B, max_edges) bool (the Gymnasium envs' ``obstacles`` /
        ``obstacle_mask``).

        Raises:
            ValueError: an episode's map has more than ``max_edges`` edges.
        """
        cache = self.__dict__.setdefault("_padded", {})
        if max_edges not in cache:
            edges = np.zeros((len(self.maps), max_edges, 4))
            mask = np.zeros((len(self.maps), max_edges), dtype=bool)
            for b, static_map in enumerate(self.maps):
                if static_map is None:
                    continue
                start, end = static_map.edges()
                if len(start) > max_edges:
                    raise ValueError(
                        f"the static map of episode row {b} has {len(start)} edges, more than "
                        f"max_obstacle_edges = {max_edges}"
                    )
                edges[b, : len(start), :2], edges[b, : len(start), 2:] = start, end
                mask[b, : len(start)] = True
            edges.setflags(write=False)
            mask.setflags(write=False)
            cache[max_edges] = (edges, mask)
        return cache[max_edges]

    def take(self, index: np.ndarray | slice) -> ObstacleArrays | None:
        """The rows ``index`` (None when they are all open floors)."""
        rows = np.arange(len(self.maps))[index]
        return ObstacleArrays.from_maps([self.maps[int(i)] for i in np.atleast_1d(rows)])


@dataclass(frozen=True)
class Observation:
    """Full-information observation of B episodes.

    Attributes:
        robot: (B, 9) px, py, vx, vy, radius, gx, gy, v_pref, theta [m, m/s, rad].
        humans: (B, N, 5) px, py, vx, vy, radius per human slot.
        human_mask: (B, N) bool, True for real humans.
        active: (B,) bool, True where the robot still acts (running episodes).
        time: (B,) episode time [s].
        dt: step length [s].
        kinematics: "holonomic", "unicycle" or "diff_drive".
        next_humans: (B, N, 5) the simulator's exact next human states, present only when the
            observation was requested with the "oracle" information setting.
        obstacles: the episodes' static maps (:class:`ObstacleArrays`), or None when every episode
            is an open floor. The native robot policies (ORCA, social force) avoid them.
        static_slots: how many of the last human slots are not humans but obstacle points appended
            by a value policy's obstacle encoding (:mod:`socialnav.sim.obstacle_points`); 0 in what
            the world observes.
        lidar: (B, beams) float32 ranges [m] of the robot's lidar (``sensing.lidar_beams``; beam angles
            ``socialnav.sim.lidar_beam_angles``), None without one.
        robot_twist: (B, 2) a differential-drive robot's forward speed v [m/s] and turn rate ω [rad/s] of
            its last step (its acceleration limits act from them; zero at an episode's start), None for the
            other kinematics.

    With non-default ``sensing`` (docs/perception.md), ``humans`` and ``human_mask`` are the humans the
    robot detects, as it detects them; the world's state and every metric stay exact.
    """

    robot: np.ndarray
    humans: np.ndarray
    human_mask: np.ndarray
    active: np.ndarray
    time: np.ndarray
    dt: float
    kinematics: str
    next_humans: np.ndarray | None = None
    obstacles: ObstacleArrays | None = None
    static_slots: int = 0
    lidar: np.ndarray | None = None
    robot_twist: np.ndarray | None = None

    @property
    def batch_size(self) -> int:
        """The number of episodes B."""
        return self.robot.shape[0]

    def take(self, index: np.ndarray | slice) -> Observation:
        """Sub-batch of episodes (copies)."""
        nxt = None if self.next_humans is None else self.next_humans[index].copy()
        walls = None if self.obstacles is None else self.obstacles.take(index)
        lidar = None if self.lidar is None else self.lidar[index].copy()
        twist = None if self.robot_twist is None else self.robot_twist[index].copy()
        return Observation(self.robot[index].copy(), self.humans[index].copy(), self.human_mask[index].copy(),
                           self.active[index].copy(), self.time[index].copy(), self.dt, self.kinematics, nxt,
                           walls, self.static_slots, lidar, twist)


def build_observation(position: np.ndarray, velocity: np.ndarray, goal: np.ndarray, radius: np.ndarray,
                      v_pref: np.ndarray, mask: np.ndarray, theta: np.ndarray, active: np.ndarray,
                      time: np.ndarray, dt: float, kinematics: str) -> Observation:
    """Assembles an Observation from the world's state arrays (agent 0 is the robot)."""
    batch = position.shape[0]
    robot = np.empty((batch, ROBOT_DIM))
    robot[:, 0:2] = position[:, 0]
    robot[:, 2:4] = velocity[:, 0]
    robot[:, ROBOT_RADIUS] = radius[:, 0]
    robot[:, 5:7] = goal[:, 0]
    robot[:, ROBOT_VPREF] = v_pref[:, 0]
    robot[:, ROBOT_THETA] = theta
    humans = np.empty((batch, position.shape[1] - 1, HUMAN_DIM))
    humans[..., 0:2] = position[:, 1:]
    humans[..., 2:4] = velocity[:, 1:]
    humans[..., HUMAN_RADIUS] = radius[:, 1:]
    human_mask = mask[:, 1:].astype(bool)
    humans[~human_mask] = 0.0  # padded slots carry no stale data
    return Observation(robot, humans, human_mask, active.copy(), time.copy(), dt, kinematics)


def check_observation(observation: Observation, name: str, kinematics: str | None = None,
                      oracle: bool = False) -> None:
    """Refuses an observation a policy would turn into a silently wrong action.

    A network given NaN picks an arbitrary action (or, argmax over NaN, the first: stop); one given
    another robot's kinematics sends (vx, vy) to a robot that reads (v, dθ). Checked: the arrays'
    shapes, the kinematics (where the policy has one), and finite values in the active episodes' robot
    rows and real humans.

    Args:
        observation: What the policy is given.
        name: The policy, for the message.
        kinematics: The kinematics the policy was made for, or None for any.
        oracle: Check ``next_humans`` too.

    Raises:
        ValueError: Naming the array, the episode row and, for humans, the slot.
    """
    if kinematics is not None and observation.kinematics != kinematics:
        raise ValueError(f"policy {name!r} was trained for a {kinematics} robot; the observation is of a "
                         f"{observation.kinematics!r} one (its actions would be read as the other kind's)")
    b, robot, humans = observation.batch_size, observation.robot, observation.humans
    if (robot.shape != (b, ROBOT_DIM) or humans.ndim != 3 or humans.shape[0] != b
            or humans.shape[2] != HUMAN_DIM):
        raise ValueError(f"policy {name!r}: observation robot must be (B, {ROBOT_DIM}) and humans "
                         f"(B, N, {HUMAN_DIM}), got "
                         f"{robot.shape} and {humans.shape}")
    if observation.human_mask.shape != humans.shape[:2]:
        raise ValueError(f"policy {name!r}: observation human_mask must be {humans.shape[:2]}, got "
                         f"{observation.human_mask.shape}")
    arrays = [("humans", humans)]
    if oracle and observation.next_humans is not None:
        if observation.next_humans.shape != humans.shape:
            raise ValueError(f"policy {name!r}: next_humans must have the humans' shape {humans.shape}, got "
                             f"{observation.next_humans.shape}")
        arrays.append(("next_humans", observation.next_humans))
    # The usual case at the cost of one sum per array (a NaN or inf makes the sum non-finite; a sum that
    # overflows only sends it to the exact check below)
    if all(np.isfinite(values.sum()) for values in (robot, *(v for _, v in arrays))):
        return
    active = np.asarray(observation.active, dtype=bool)
    bad = np.flatnonzero(active & ~np.all(np.isfinite(robot), axis=1))
    if bad.size:
        raise ValueError(f"policy {name!r}: observation robot row {int(bad[0])} is not finite: "
                         f"{robot[bad[0]].tolist()}")
    real = observation.human_mask & active[:, None]
    for label, values in arrays:
        bad_slots = np.argwhere(real & ~np.all(np.isfinite(values), axis=2))
        if bad_slots.size:
            row, slot = (int(v) for v in bad_slots[0])
            raise ValueError(f"policy {name!r}: observation {label}[{row}, {slot}] (a real human) is not "
                             f"finite: {values[row, slot].tolist()}")
