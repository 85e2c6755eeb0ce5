"""A trained policy-gradient actor (``socialnav train`` with PPO) behind the project's ``Policy`` interface.

The network is recurrent over time, while ``Policy.act`` receives one batched observation per step
and no episode boundaries: the GRU state is kept per batch slot and zeroed wherever a slot's episode
time is 0 (the world refills a finished slot with a fresh episode at time 0), or when the batch size
changes. Deterministic evaluation acts with the mean of the Gaussian, squashed as in training.

A network trained among walls reads the obstacle points of its ``obstacle_encoding`` after the human
slots (:func:`~socialnav.policies.learned.attn_graph.observation_tensors`), from each episode's map
in the observation; on an open floor its point slots are all masked.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from socialnav.policies.learned.attn_graph import squash_actions
from socialnav.policies.learned.lookahead_inputs import network_composition
from socialnav.policies.learned.ppo_inputs import network_inputs, network_sensors
from socialnav.sim.observation import Observation
from socialnav.sim.obstacle_points import ObstaclePoints
from socialnav.sim.parts.base import NETWORK_PARTS


class RecurrentActorPolicy:
    """Acts with a recurrent actor-critic (e.g. :class:`AttnGraphNet`) one step at a time.

    Args:
        name: the registered policy name.
        network: the actor-critic.
        kinematics, rotation_limit, dt: the world the network was trained for.
        diff_drive: a differential drive's limits (``DiffDriveSettings.to_dict()``), required for one: its
            actions span [-max_reverse_speed, v_pref] (``squash_actions``).
        action_squash: how a sample becomes an action (``attn_graph.ACTION_SQUASHES``; the record's
            ``recorded_action_squash``), None for the one PPO trains ``kinematics`` with.
        deterministic: act with the mean action (evaluation); False samples from the Gaussian with
            ``generator``.
        obstacle_encoding: the obstacle points the network reads
            (:class:`~socialnav.sim.obstacle_points.ObstaclePoints` or its dict), or None for a
            network trained without walls.
        observation_parts: the named observation parts the network reads (its record's
            ``observation_parts``).
    """

    def __init__(
        self,
        name: str,
        network: torch.nn.Module,
        *,
        kinematics: str,
        rotation_limit: float,
        dt: float,
        device: str | torch.device = "cpu",
        deterministic: bool = True,
        generator: torch.Generator | None = None,
        checkpoint: Path | None = None,
        preset_mismatch: list[str] | None = None,
        obstacle_encoding: ObstaclePoints | dict | None = None,
        observation_parts: Sequence[str] = NETWORK_PARTS,
        diff_drive: Mapping[str, Any] | None = None,
        action_squash: str | None = None,
    ) -> None:
        if kinematics == "diff_drive" and diff_drive is None:
            raise ValueError("a diff_drive actor needs the robot's diff_drive limits (its reverse speed)")
        self.max_reverse_speed = float((diff_drive or {}).get("max_reverse_speed", 0.0))
        self.name = name
        self.network = network
        self.kinematics = kinematics
        self.action_squash = action_squash
        self.rotation_limit = float(rotation_limit)
        self.dt = float(dt)
        self.device = torch.device(device)
        self.deterministic = deterministic
        self.generator = generator
        self.checkpoint = checkpoint
        self.preset_mismatch = list(preset_mismatch or [])
        self.information = "constant_velocity" if network.prediction_steps else "none"
        self.obstacle_encoding = (
            None if obstacle_encoding is None else ObstaclePoints.from_dict(obstacle_encoding)
        )
        self.observation_parts = tuple(observation_parts)
        network_composition(self.obstacle_encoding, self.observation_parts)  # refuses parts it cannot read
        #: The sensing settings the network brings to the world it acts in (its lidar), {} for none.
        self.sensors = network_sensors(network)
        self._h: torch.Tensor | None = None

    def reset(self) -> None:
        """Forgets every slot's recurrent state."""
        self._h = None

    @torch.no_grad()
    def act(self, observation: Observation) -> np.ndarray:
        """Actions of the actor for B episodes, carrying its recurrent state between calls.

        Args:
            observation: The world's observation of B episodes.

        Returns:
            (B, 2) float64 robot velocities [m/s]: the mean action, or a sample where not deterministic.
        """
        net = self.network
        b = observation.batch_size
        if self._h is None or self._h.shape[0] != b:
            self._h = net.initial_state(b, self.device)
        start = torch.as_tensor(observation.time == 0.0, device=self.device)
        robot, humans, mask = network_inputs(
            net, observation, self.dt, self.device, self.obstacle_encoding, self.observation_parts
        )
        mean, _, self._h = net.step(robot, humans, mask, self._h, start)
        raw = mean
        if not self.deterministic:
            noise = torch.randn(mean.shape, generator=self.generator, dtype=mean.dtype)
            raw = mean + noise.to(self.device) * net.log_std.exp()
        actions = squash_actions(
            raw.double().cpu().numpy(), self.kinematics, observation.robot[:, 7], self.rotation_limit,
            self.max_reverse_speed, self.action_squash,
        )
        actions[~observation.active] = 0.0
        return actions

    def describe(self) -> dict[str, Any]:
        """The record stored with results: policy, information, checkpoint and network parameters."""
        return {
            "policy": self.name,
            "information": self.information,
            "checkpoint": None if self.checkpoint is None else str(self.checkpoint),
            "deterministic": self.deterministic,
            **({"preset_mismatch_allowed": self.preset_mismatch} if self.preset_mismatch else {}),
            **(
                {"obstacle_encoding": self.obstacle_encoding.to_dict()}
                if self.obstacle_encoding is not None
                else {}
            ),
            **({"sensors": dict(self.sensors)} if self.sensors else {}),
            # its goal is its global route's (lidar_ppo's route_goal): a map-based planner it relies on
            **({"route_goal": True} if getattr(self.network, "route_goal", False) else {}),
        }
