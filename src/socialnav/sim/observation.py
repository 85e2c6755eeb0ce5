"""Batched observations: what a policy sees of the world (CrowdSim's full information)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

ROBOT_PX, ROBOT_PY, ROBOT_VX, ROBOT_VY, ROBOT_RADIUS, ROBOT_GX, ROBOT_GY, ROBOT_VPREF, ROBOT_THETA = range(9)
HUMAN_PX, HUMAN_PY, HUMAN_VX, HUMAN_VY, HUMAN_RADIUS = range(5)
ROBOT_DIM = 9
HUMAN_DIM = 5


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
        kinematics: "holonomic" or "unicycle".
        next_humans: (B, N, 5) the simulator's exact next human states, present only when the
            observation was requested with the "oracle" information setting.
    """

    robot: np.ndarray
    humans: np.ndarray
    human_mask: np.ndarray
    active: np.ndarray
    time: np.ndarray
    dt: float
    kinematics: str
    next_humans: np.ndarray | None = None

    @property
    def batch_size(self) -> int:
        return self.robot.shape[0]

    def take(self, index: np.ndarray | slice) -> Observation:
        """Sub-batch of episodes (copies)."""
        nxt = None if self.next_humans is None else self.next_humans[index].copy()
        return Observation(self.robot[index].copy(), self.humans[index].copy(), self.human_mask[index].copy(),
                           self.active[index].copy(), self.time[index].copy(), self.dt, self.kinematics, nxt)


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
