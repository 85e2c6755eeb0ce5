"""A lidar actor-critic for PPO (``lidar_ppo``): the robot's state and goal plus its 2-D lidar scan.

The policy perceives walls and people only as its lidar does (docs/perception.md), as the lidar
policies of DRL-VO (Xie & Dames, "DRL-VO: Learning to Navigate Through Crowded Dynamic Scenes Using
Velocity Obstacles", T-RO 2023), robot_sf and social-jym do: no detections, no map. The scan (its
``lidar_beams`` readings, divided by ``lidar_range``) goes through two circular 1-D convolutions
(a beam's neighbours on both sides, the scan wrapping round behind the robot), whose output joins the
normalised robot features in two tanh MLPs, the actor's and the critic's (CleanRL's continuous-action
PPO agent). No recurrence: the trainer's recurrent state is a dummy the network passes through.

The trainer and :class:`~socialnav.policies.learned.ppo_policy.RecurrentActorPolicy` hand the scan in
as the last ``lidar_beams`` columns of the robot tensor (:mod:`socialnav.policies.learned.ppo_inputs`);
the human slots they also pass are not read.
"""

from __future__ import annotations

import torch
from torch import nn

from socialnav.policies.learned.attn_graph import OBS_CLIP, ROBOT_FEATURES, ObservationStatistics, _fold
from socialnav.policies.learned.ppo_mlp import actor_critic_mlps

__all__ = ["LidarActorCritic"]


class LidarActorCritic(ObservationStatistics):
    """Actor-critic over the robot's features and its lidar scan (module docstring).

    Args:
        lidar_beams: the scan's readings (the world's ``sensing.lidar_beams`` it acts in).
        lidar_range: the lidar's maximum range [m] (readings are divided by it).
        channels: the convolutions' channels.
        hidden: the MLPs' width.
        normalize_obs: normalise the robot's features by their running statistics.
        log_std_init: the Gaussian's initial log standard deviation.
    """

    gru_hidden = 1  # the trainer's recurrent state: unused
    prediction_steps = 0  # reads no human slots: none are predicted
    input_dim = 2  # the (unread) human slots' width the trainer allocates

    def __init__(
        self,
        lidar_beams: int = 180,
        lidar_range: float = 10.0,
        channels: int = 16,
        hidden: int = 256,
        normalize_obs: bool = True,
        log_std_init: float = 0.0,
    ) -> None:
        super().__init__()
        if lidar_beams < 4 or not lidar_range > 0 or channels < 1 or hidden < 1:
            raise ValueError(f"lidar_beams must be >= 4, lidar_range > 0, channels and hidden >= 1, got "
                             f"{lidar_beams}, {lidar_range}, {channels}, {hidden}")
        self._kwargs = dict(lidar_beams=lidar_beams, lidar_range=float(lidar_range), channels=channels,
                            hidden=hidden, normalize_obs=normalize_obs, log_std_init=log_std_init)
        self.lidar_beams, self.lidar_range = int(lidar_beams), float(lidar_range)
        self.normalize_obs = normalize_obs
        self.encoder = nn.Sequential(
            nn.Conv1d(1, channels, 5, stride=2, padding=2, padding_mode="circular"),
            nn.ReLU(),
            nn.Conv1d(channels, channels, 3, stride=2, padding=1, padding_mode="circular"),
            nn.ReLU(),
            nn.Flatten(),
        )
        with torch.no_grad():
            scan_features = self.encoder(torch.zeros(1, 1, self.lidar_beams)).shape[1]
        self.actor, self.critic = actor_critic_mlps(ROBOT_FEATURES + scan_features, hidden)
        self.log_std = nn.Parameter(torch.full((2,), float(log_std_init)))
        self._init_obs_stats()

    @property
    def robot_width(self) -> int:
        """The robot tensor's width the network reads: the robot's features, then the scan."""
        return ROBOT_FEATURES + self.lidar_beams

    def model_kwargs(self) -> dict:
        """The constructor's keyword arguments, saved with the checkpoint to rebuild the network."""
        return dict(self._kwargs)

    def sensors(self) -> dict:
        """The sensing settings the network needs in the world it acts in (its lidar)."""
        return {"lidar_beams": self.lidar_beams, "lidar_range": self.lidar_range}

    def initial_state(self, batch: int, device: torch.device | str = "cpu") -> torch.Tensor:
        """A placeholder recurrent state, (batch, 1) zeros."""
        return torch.zeros(batch, 1, device=device)

    @torch.no_grad()
    def update_obs_stats(self, robot: torch.Tensor, humans: torch.Tensor, mask: torch.Tensor) -> None:
        """Folds the robot's features (not the scan, which is scaled by the range) into the statistics."""
        state = robot[..., :ROBOT_FEATURES].reshape(-1, ROBOT_FEATURES)
        _fold(self.obs_count, self.robot_mean, self.robot_var, state)

    def features(self, robot: torch.Tensor) -> torch.Tensor:
        """(M, width): the normalised robot features and the scan's encoding."""
        state, scan = robot[:, :ROBOT_FEATURES], robot[:, ROBOT_FEATURES:]
        if scan.shape[1] != self.lidar_beams:
            raise ValueError(f"the network reads a {self.lidar_beams}-beam scan, got {scan.shape[1]} "
                             "readings")
        if self.normalize_obs:
            mean, var = self.robot_mean.to(state.dtype), self.robot_var.to(state.dtype)
            state = ((state - mean) / torch.sqrt(var + 1e-8)).clamp(-OBS_CLIP, OBS_CLIP)
        encoded = self.encoder((scan / self.lidar_range).unsqueeze(1))
        return torch.cat([state, encoded], -1)

    def step(self, robot, humans, mask, h, start):
        """Action mean (B, 2), value (B,) and the unchanged dummy state (the trainer's interface)."""
        x = self.features(robot)
        return self.actor(x), self.critic(x).squeeze(-1), h

    def sequence(self, robot, humans, mask, h0, starts):
        """Means (T, B, 2) and values (T, B) of T steps of B episodes (no recurrence)."""
        t, b = robot.shape[:2]
        x = self.features(robot.reshape(t * b, -1))
        return self.actor(x).view(t, b, 2), self.critic(x).view(t, b)
