"""What a PPO network reads from a world's observation, for the trainer and the acting policy alike.

Every PPO network takes (robot, humans, mask) tensors
(:func:`~socialnav.policies.learned.attn_graph.observation_tensors`); a network that reads the robot's
sensors (the lidar of ``sensing.lidar_beams``; :mod:`socialnav.policies.learned.lidar_net`) declares
``sensors()``, the sensing settings it needs, and gets the readings as the last columns of the robot
tensor, so the rollout, the update and the policy keep one tensor layout for every network. A network
with ``twist_features`` (a differential-drive robot's) gets the robot's (v, ω) right after its features.
A network with ``route_goal`` reads its goal as the robot's route around the walls heads for it
(:func:`socialnav.maps.routes.route_goals`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np
import torch

from socialnav.maps.routes import route_goals
from socialnav.policies.learned.attn_graph import ROBOT_FEATURES, observation_tensors
from socialnav.sim.observation import Observation
from socialnav.sim.parts.base import NETWORK_PARTS

__all__ = ["network_inputs", "network_sensors", "robot_width", "with_route_goals"]


def network_sensors(net: Any) -> dict[str, Any]:
    """The sensing settings ``net`` needs in its world (empty: it reads the world's detections only)."""
    sensors = getattr(net, "sensors", None)
    return dict(sensors()) if callable(sensors) else {}


def robot_width(net: Any) -> int:
    """The width of the robot tensor ``net`` reads: the robot's features, then its sensors' readings."""
    return int(getattr(net, "robot_width", getattr(net, "robot_state_width", ROBOT_FEATURES)))


def with_route_goals(obs: Observation) -> Observation:
    """``obs`` with each robot's goal replaced by the point its route around the walls heads for."""
    robot = np.array(obs.robot, dtype=np.float64)
    robot[:, 5:7] = route_goals(robot, None if obs.obstacles is None else obs.obstacles.native)
    return dataclasses.replace(obs, robot=robot)


def network_inputs(net: Any, obs: Observation, dt: float, device: torch.device | str,
                   encoding: Any = None, parts: Sequence[str] = NETWORK_PARTS
                   ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(robot, humans, mask) for ``net``: ``observation_tensors``, the twist and lidar after the robot's.

    Raises:
        ValueError: The network reads a lidar the observation does not have, or one of another size; or
            it reads a differential drive's twist and the observation is of another robot.
    """
    if getattr(net, "route_goal", False) and obs.obstacles is not None:
        obs = with_route_goals(obs)
    robot, humans, mask = observation_tensors(obs, dt, net.prediction_steps, device, encoding, parts)
    if getattr(net, "twist_features", False):
        if obs.robot_twist is None:
            raise ValueError(f"the network reads a differential-drive robot's (v, ω); the observation is "
                             f"of a {obs.kinematics} robot (docs/kinematics.md)")
        twist = torch.as_tensor(obs.robot_twist, dtype=robot.dtype, device=robot.device)
        robot = torch.cat([robot, twist], -1)
    beams = getattr(net, "lidar_beams", 0)
    if beams:
        scan = obs.lidar
        if scan is None or scan.shape[1] != beams:
            got = "no lidar" if scan is None else f"a {scan.shape[1]}-beam lidar"
            raise ValueError(f"the network reads a {beams}-beam lidar, the observation has {got} (the "
                             "world's sensing.lidar_beams; docs/perception.md)")
        robot = torch.cat([robot, torch.as_tensor(scan, dtype=robot.dtype, device=robot.device)], -1)
    return robot, humans, mask
