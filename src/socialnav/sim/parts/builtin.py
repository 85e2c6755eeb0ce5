"""The built-in observation parts: robot, humans, obstacle points and edges, lidar, robot_twist.

Each computes its arrays from the world's state (:class:`~socialnav.sim.parts.base.PartInput`) in the
layout of a :class:`~socialnav.sim.parts.base.PartContext`; the columns are those of
:data:`~socialnav.sim.observation.ROBOT_COLUMNS` and :data:`~socialnav.sim.observation.HUMAN_COLUMNS`
(docs/internals.md, "Observation"). Layouts (K human slots, P obstacle points, E edges):

================  =====================  ===================================================
part              key                    world frame / robot frame
================  =====================  ===================================================
robot             robot                  (9,) world columns / (6,) dg, v_pref, theta', radius, vx', vy'
humans            humans                 (K, 5) / (K, 7) px', py', vx', vy', radius, da, radius_sum
humans            human_mask             (K,) int8, 1 for a real human
obstacle_points   obstacle_points        (P, 2) px, py / (P, 3) px', py', distance to the robot
obstacle_points   obstacle_point_mask    (P,) int8, 1 for a real point
obstacle_edges    obstacles              (E, 4) x1, y1, x2, y2 (world frame only; the raw env's)
obstacle_edges    obstacle_mask          (E,) int8, 1 for a real edge
lidar             lidar                  (beams,) ranges along the beams (world.sensing), both frames
robot_twist       robot_twist            (2,) a diff_drive robot's v, ω of its last step, both frames
================  =====================  ===================================================

Lengths are in units of ``length_scale``, speeds of ``speed_scale``, angles in radians; rot is the robot's
heading towards its goal. In the raw env's layout (``PartContext.raw``) ``robot`` and ``humans`` are the
world's arrays as they are (slot order, the scenario's own human count).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from socialnav.sim.observation import HUMAN_COLUMNS, ROBOT_COLUMNS
from socialnav.sim.parts.base import BOUND, ObservationPart, PartContext, PartInput
from socialnav.sim.parts.registry import register_observation_part
from socialnav.sim.settings import HEADED_KINEMATICS

#: The obstacle points' columns (:mod:`socialnav.sim.obstacle_points`; as agents they take the humans').
OBSTACLE_COLUMNS = {"world": ("px", "py"), "robot": ("px", "py", "distance")}
#: The obstacle edges' columns (world frame).
EDGE_COLUMNS = {"world": ("x1", "y1", "x2", "y2")}


def _mask_space(n: int) -> Any:
    from gymnasium import spaces

    # Gymnasium has no MultiBinary(0): a crowd-free scenario's empty mask is an empty Box
    return spaces.MultiBinary(n) if n else spaces.Box(0, 1, (0,), np.int8)


@register_observation_part
class RobotPart(ObservationPart):
    """The robot's state and goal: position, velocity, radius, goal, preferred speed, heading."""

    name = "robot"
    reads_maps = False
    description = "the robot's state and goal (world: 9 columns; robot frame: 6)"
    columns = {"robot": ROBOT_COLUMNS}

    def compute(self, data: PartInput, ctx: PartContext) -> dict[str, np.ndarray]:
        """(B, 9) world rows or (B, 6) robot-frame rows, scaled, in the context's dtype."""
        robot = data.robot
        if ctx.raw:
            return {"robot": robot}
        robot = np.asarray(robot, dtype=np.float64)
        if ctx.frame == "world":
            r = robot.copy()
            r[:, [0, 1, 4, 5, 6]] /= ctx.length_scale
            r[:, [2, 3, 7]] /= ctx.speed_scale
        else:
            rot, c, s = data.goal_frame
            dx, dy = robot[:, 5] - robot[:, 0], robot[:, 6] - robot[:, 1]
            theta = robot[:, 8] - rot if ctx.kinematics in HEADED_KINEMATICS else np.zeros_like(rot)
            r = np.stack(
                [
                    np.hypot(dx, dy),
                    robot[:, 7],
                    theta,
                    robot[:, 4],
                    robot[:, 2] * c + robot[:, 3] * s,
                    robot[:, 3] * c - robot[:, 2] * s,
                ],
                axis=1,
            )
            r[:, [0, 3]] /= ctx.length_scale
            r[:, [1, 4, 5]] /= ctx.speed_scale
        return {"robot": r.astype(ctx.np_dtype)}


@register_observation_part
class HumansPart(ObservationPart):
    """The humans: K slots of human rows with their mask (the nearest K real humans, real ones first)."""

    name = "humans"
    reads_maps = False
    description = "the humans, K slots with a mask (world: 5 columns each; robot frame: 7)"
    columns = {"humans": HUMAN_COLUMNS}

    def spaces(self, ctx: PartContext) -> dict[str, Any]:
        """``humans`` (K, width) and ``human_mask`` (K,)."""
        from gymnasium import spaces

        k = ctx.human_slots
        return {
            "humans": spaces.Box(-BOUND, BOUND, shape=(k, self.width("humans", ctx.frame)),
                                 dtype=ctx.np_dtype),
            "human_mask": _mask_space(k),
        }

    def compute(self, data: PartInput, ctx: PartContext) -> dict[str, np.ndarray]:
        """(B, K, 5|7) rows, zero where padded, and the (B, K) int8 mask."""
        if ctx.raw:
            return {"humans": data.humans, "human_mask": data.human_mask.astype(np.int8)}
        humans, mask = data.fixed_humans(ctx.human_slots)
        if ctx.frame == "world":
            h = humans.copy()
            h[..., [0, 1, 4]] /= ctx.length_scale
            h[..., [2, 3]] /= ctx.speed_scale
        else:
            robot = data.robot
            _, c, s = data.goal_frame
            c, s = c[:, None], s[:, None]
            hx = humans[..., 0] - robot[:, None, 0]
            hy = humans[..., 1] - robot[:, None, 1]
            h = np.stack(
                [
                    hx * c + hy * s,
                    hy * c - hx * s,
                    humans[..., 2] * c + humans[..., 3] * s,
                    humans[..., 3] * c - humans[..., 2] * s,
                    humans[..., 4],
                    np.hypot(hx, hy),
                    humans[..., 4] + robot[:, None, 4],
                ],
                axis=-1,
            )
            h[..., [0, 1, 4, 5, 6]] /= ctx.length_scale
            h[..., [2, 3]] /= ctx.speed_scale
        h[~mask] = 0.0
        return {"humans": h.astype(ctx.np_dtype), "human_mask": mask.astype(np.int8)}

    def agents(self, data: PartInput, ctx: PartContext) -> tuple[np.ndarray, np.ndarray]:
        """The human slots as they are: (B, N, 5) float64 rows and (B, N) bool mask."""
        return np.asarray(data.humans, dtype=np.float64), np.asarray(data.human_mask, dtype=bool)


@register_observation_part
class ObstaclePointsPart(ObservationPart):
    """The obstacle outlines' points nearest the robot (:mod:`socialnav.sim.obstacle_points`)."""

    name = "obstacle_points"
    description = ("the P obstacle-outline points nearest the robot, with a mask (world: px, py; robot "
                   "frame: px, py, distance); the networks read them as standing agents")
    columns = {"obstacle_points": OBSTACLE_COLUMNS}
    static = True

    def spaces(self, ctx: PartContext) -> dict[str, Any]:
        """``obstacle_points`` (P, width) and ``obstacle_point_mask`` (P,); none without an encoding."""
        from gymnasium import spaces

        encoding = ctx.obstacle_points
        if encoding is None:
            return {}
        p = encoding.count
        shape = (p, self.width("obstacle_points", ctx.frame))
        return {
            "obstacle_points": spaces.Box(-BOUND, BOUND, shape=shape, dtype=ctx.np_dtype),
            "obstacle_point_mask": spaces.MultiBinary(p),
        }

    def compute(self, data: PartInput, ctx: PartContext) -> dict[str, np.ndarray]:
        """(B, P, 2|3) points, zero where padded, and the (B, P) int8 mask."""
        encoding = ctx.obstacle_points
        if encoding is None:
            return {}
        robot = np.asarray(data.robot, dtype=np.float64)
        points, mask = encoding.nearest(robot[:, :2], data.maps)
        if ctx.frame == "world":
            out = points.copy()
        else:
            dx = points[..., 0] - robot[:, None, 0]
            dy = points[..., 1] - robot[:, None, 1]
            _, c, s = data.goal_frame
            c, s = c[:, None], s[:, None]
            out = np.stack([dx * c + dy * s, dy * c - dx * s, np.hypot(dx, dy)], axis=-1)
        out /= ctx.length_scale
        out[~mask] = 0.0
        return {"obstacle_points": out.astype(ctx.np_dtype), "obstacle_point_mask": mask.astype(np.int8)}

    def agents(self, data: PartInput, ctx: PartContext) -> tuple[np.ndarray, np.ndarray] | None:
        """The points as standing agents (px, py, 0, 0, radius): (B, P, 5) and the (B, P) mask."""
        encoding = ctx.obstacle_points
        if encoding is None:
            return None
        return encoding.agents(np.asarray(data.robot, dtype=np.float64)[:, :2], data.maps)


@register_observation_part
class ObstacleEdgesPart(ObservationPart):
    """The episode's obstacle edges, zero-padded (the raw Gymnasium env's ``obstacles``)."""

    name = "obstacle_edges"
    description = "the episode's obstacle edges (E, 4) with a mask, world frame (the raw env's walls)"
    columns = {"obstacles": EDGE_COLUMNS}

    def check_context(self, ctx: PartContext) -> None:
        """Refuses every layout but the raw env's, whose edge count E is its world's.

        Raises:
            ValueError: A learner's layout (``ObservationSettings.parts``), which has no edge count.
        """
        super().check_context(ctx)
        if not ctx.raw:
            raise ValueError("observation part 'obstacle_edges' is the raw env's (E, its world's edge "
                             "count); a learner's observation (ObservationSettings.parts) shows the walls "
                             "with the part 'obstacle_points' (ObservationSettings.obstacle_points, e.g. 16) "
                             "or 'lidar'")

    def spaces(self, ctx: PartContext) -> dict[str, Any]:
        """``obstacles`` (E, 4) and ``obstacle_mask`` (E,); none where E = 0."""
        from gymnasium import spaces

        e = ctx.max_edges
        if not e:
            return {}
        return {
            "obstacles": spaces.Box(-BOUND, BOUND, shape=(e, 4), dtype=ctx.np_dtype),
            "obstacle_mask": spaces.MultiBinary(e),
        }

    def compute(self, data: PartInput, ctx: PartContext) -> dict[str, np.ndarray]:
        """(B, E, 4) edges and the (B, E) int8 mask (zeros on an open floor)."""
        e = ctx.max_edges
        if not e:
            return {}
        walls = data.obstacles
        if walls is None:
            b = data.batch_size
            return {"obstacles": np.zeros((b, e, 4), dtype=ctx.np_dtype),
                    "obstacle_mask": np.zeros((b, e), dtype=np.int8)}
        edges, mask = walls.padded_edges(e)
        edges = edges / ctx.length_scale if ctx.length_scale != 1.0 else edges.copy()
        return {"obstacles": edges.astype(ctx.np_dtype, copy=False), "obstacle_mask": mask.astype(np.int8)}


@register_observation_part
class LidarPart(ObservationPart):
    """The robot's 2-D lidar scan (``world.sensing.lidar_beams`` beams; docs/perception.md)."""

    name = "lidar"
    reads_maps = False
    sees_walls = True
    sensor_keys = ("lidar",)
    description = "the robot's 2-D lidar: (beams,) ranges along the beams about its heading (world.sensing)"
    columns = {"lidar": {"world": ("range",), "robot": ("range",)}}

    def spaces(self, ctx: PartContext) -> dict[str, Any]:
        """``lidar`` (beams,) in [0, lidar_range / length_scale], float32 in the raw env's layout too.

        Raises:
            ValueError: The world has no lidar (``sensing.lidar_beams`` is 0).
        """
        from gymnasium import spaces

        sensing = _lidar_sensing(ctx)
        dtype = np.float32 if ctx.raw else ctx.np_dtype
        # the largest reading as compute() derives it from the world's float32 scan (a no-return beam
        # reads float32(lidar_range), which may round above lidar_range), so that every reading is inside
        high = float(np.float32(sensing.lidar_range)) / ctx.length_scale
        if not ctx.raw:
            high = float(np.asarray(high).astype(dtype))
        return {"lidar": spaces.Box(0.0, high, shape=(sensing.lidar_beams,), dtype=dtype)}

    def compute(self, data: PartInput, ctx: PartContext) -> dict[str, np.ndarray]:
        """(B, beams) ranges divided by ``length_scale`` (the world's float32 scans as they are when raw).

        Raises:
            ValueError: The input carries no scan (a world without lidar).
        """
        scan = data.sensors.get("lidar")
        if scan is None:
            raise ValueError("observation part 'lidar': the observation has no lidar scan (set "
                             "world.sensing.lidar_beams; docs/perception.md)")
        if ctx.raw:
            return {"lidar": np.asarray(scan, dtype=np.float32)}
        return {"lidar": (np.asarray(scan, dtype=np.float64) / ctx.length_scale).astype(ctx.np_dtype)}


def _lidar_sensing(ctx: PartContext) -> Any:
    sensing = ctx.sensing
    if sensing is None or not getattr(sensing, "lidar_beams", 0):
        raise ValueError("observation part 'lidar' needs a world with a lidar (world.sensing.lidar_beams > "
                         "0; docs/perception.md)")
    return sensing


@register_observation_part
class RobotTwistPart(ObservationPart):
    """A differential-drive robot's forward speed and turn rate of its last step (docs/kinematics.md).

    Its acceleration limits act from them, so a policy needs them to know what it can do next.
    """

    name = "robot_twist"
    reads_maps = False
    sensor_keys = ("robot_twist",)
    description = "a diff_drive robot's (v, ω) of its last step, from which its acceleration limits act"
    columns = {"robot_twist": {"world": ("v", "omega"), "robot": ("v", "omega")}}

    def spaces(self, ctx: PartContext) -> dict[str, Any]:
        """``robot_twist`` (2,): v [m/s] divided by ``speed_scale``, ω [rad/s].

        Raises:
            ValueError: The robot is not a differential drive.
        """
        from gymnasium import spaces

        if ctx.kinematics != "diff_drive":
            raise ValueError("observation part 'robot_twist' needs a diff_drive robot (world.kinematics; "
                             f"docs/kinematics.md), not a {ctx.kinematics} one")
        dtype = np.float64 if ctx.raw else ctx.np_dtype
        return {"robot_twist": spaces.Box(-BOUND, BOUND, shape=(2,), dtype=dtype)}

    def compute(self, data: PartInput, ctx: PartContext) -> dict[str, np.ndarray]:
        """(B, 2) v / ``speed_scale`` and ω (the world's float64 values as they are when raw).

        Raises:
            ValueError: The input carries no twist (a robot of other kinematics).
        """
        twist = data.sensors.get("robot_twist")
        if twist is None:
            raise ValueError("observation part 'robot_twist': the observation has no twist (a diff_drive "
                             "robot's; docs/kinematics.md)")
        twist = np.asarray(twist, dtype=np.float64)
        if ctx.raw:
            return {"robot_twist": twist}
        out = twist.copy()
        out[:, 0] /= ctx.speed_scale
        return {"robot_twist": out.astype(ctx.np_dtype)}
