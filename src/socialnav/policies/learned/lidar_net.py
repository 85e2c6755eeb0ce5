"""A lidar actor-critic for PPO (``lidar_ppo``): the robot's state and goal plus its 2-D lidar scan.

The policy perceives walls and people only as its lidar does (docs/perception.md), as the lidar
policies of DRL-VO (Xie & Dames, "DRL-VO: Learning to Navigate Through Crowded Dynamic Scenes Using
Velocity Obstacles", T-RO 2023), robot_sf and social-jym do: no detections, no map. The scan (its
``lidar_beams`` readings, divided by ``lidar_range``) goes through two circular 1-D convolutions
(a beam's neighbours on both sides, the scan wrapping round behind the robot), whose output joins the
normalised robot features in two tanh MLPs, the actor's and the critic's (CleanRL's continuous-action
PPO agent).

One scan shows where people are, not where they go. With ``lidar_history`` k > 1 the convolutions read
the last k scans as k channels (the current one first), as DRL-VO reads its scan history: a person's
motion is the shift of its returns between channels. The earlier scans are the network's recurrent
state, which the trainer already stores, resets and replays for its recurrent networks: at an episode's
first step the history is the first scan repeated (nothing has moved yet). With k = 1 the state is a
dummy the network passes through.

With ``route_goal`` the goal the robot's features describe is its global planner's: the point its shortest
route around the map's walls heads for (:func:`socialnav.maps.routes.route_goals`: towards the route's
first corner, as far as the route is long; the goal itself once in sight), planned afresh each step, as
DRL-VO reads the sub-goal of a global path planner on the map. Walls and people are still perceived
through the lidar alone; the map gives the way through rooms and doors, which a scan cannot show.

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
        lidar_history: the scans read each step, the current one and the k - 1 before it.
        route_goal: read the goal as the robot's route around the walls heads for it (module docstring).
        channels: the convolutions' channels.
        hidden: the MLPs' width.
        normalize_obs: normalise the robot's features by their running statistics.
        log_std_init: the Gaussian's initial log standard deviation.
    """

    prediction_steps = 0  # reads no human slots: none are predicted
    input_dim = 2  # the (unread) human slots' width the trainer allocates

    def __init__(
        self,
        lidar_beams: int = 180,
        lidar_range: float = 10.0,
        lidar_history: int = 1,
        route_goal: bool = False,
        channels: int = 16,
        hidden: int = 256,
        normalize_obs: bool = True,
        log_std_init: float = 0.0,
    ) -> None:
        super().__init__()
        if lidar_beams < 4 or not lidar_range > 0 or lidar_history < 1 or channels < 1 or hidden < 1:
            raise ValueError(f"lidar_beams must be >= 4, lidar_range > 0, lidar_history, channels and hidden "
                             f">= 1, got {lidar_beams}, {lidar_range}, {lidar_history}, {channels}, {hidden}")
        self._kwargs = dict(lidar_beams=lidar_beams, lidar_range=float(lidar_range), channels=channels,
                            hidden=hidden, normalize_obs=normalize_obs, log_std_init=log_std_init)
        if lidar_history > 1:  # (the networks trained before it existed are rebuilt without the key)
            self._kwargs["lidar_history"] = lidar_history
        if route_goal:
            self._kwargs["route_goal"] = True
        self.route_goal = bool(route_goal)
        self.lidar_beams, self.lidar_range = int(lidar_beams), float(lidar_range)
        self.lidar_history = int(lidar_history)
        # the trainer's recurrent state: the k - 1 earlier scans (a dummy column without a history)
        self.gru_hidden = max(1, (self.lidar_history - 1) * self.lidar_beams)
        self.normalize_obs = normalize_obs
        self.encoder = nn.Sequential(
            nn.Conv1d(self.lidar_history, channels, 5, stride=2, padding=2, padding_mode="circular"),
            nn.ReLU(),
            nn.Conv1d(channels, channels, 3, stride=2, padding=1, padding_mode="circular"),
            nn.ReLU(),
            nn.Flatten(),
        )
        with torch.no_grad():
            scan_features = self.encoder(torch.zeros(1, self.lidar_history, self.lidar_beams)).shape[1]
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
        """The recurrent state before any step, (batch, gru_hidden) zeros (replaced at the first step)."""
        return torch.zeros(batch, self.gru_hidden, device=device)

    @torch.no_grad()
    def update_obs_stats(self, robot: torch.Tensor, humans: torch.Tensor, mask: torch.Tensor) -> None:
        """Folds the robot's features (not the scan, which is scaled by the range) into the statistics."""
        state = robot[..., :ROBOT_FEATURES].reshape(-1, ROBOT_FEATURES)
        _fold(self.obs_count, self.robot_mean, self.robot_var, state)

    def _scan(self, robot: torch.Tensor) -> torch.Tensor:
        scan = robot[..., ROBOT_FEATURES:]
        if scan.shape[-1] != self.lidar_beams:
            raise ValueError(f"the network reads a {self.lidar_beams}-beam scan, got {scan.shape[-1]} "
                             "readings")
        return scan

    def _history(self, scan: torch.Tensor, h: torch.Tensor, start: torch.Tensor) -> torch.Tensor:
        """(B, k, beams): this step's scan, then the k - 1 before it.

        Where an episode starts, its first scan stands for the earlier ones.
        """
        k, b = self.lidar_history, scan.shape[0]
        if k == 1:
            return scan.unsqueeze(1)
        earlier = h.reshape(b, k - 1, self.lidar_beams).to(scan.dtype)
        earlier = torch.where(start.reshape(b, 1, 1), scan.unsqueeze(1).expand(b, k - 1, -1), earlier)
        return torch.cat([scan.unsqueeze(1), earlier], 1)

    def _next_state(self, scans: torch.Tensor, h: torch.Tensor) -> torch.Tensor:
        if self.lidar_history == 1:
            return h
        return scans[:, :-1].reshape(scans.shape[0], -1).to(h.dtype)

    def features(self, robot: torch.Tensor, scans: torch.Tensor) -> torch.Tensor:
        """(M, width): the normalised robot features and the encoding of the scans (M, k, beams)."""
        state = robot[:, :ROBOT_FEATURES]
        if self.normalize_obs:
            mean, var = self.robot_mean.to(state.dtype), self.robot_var.to(state.dtype)
            state = ((state - mean) / torch.sqrt(var + 1e-8)).clamp(-OBS_CLIP, OBS_CLIP)
        encoded = self.encoder(scans / self.lidar_range)
        return torch.cat([state, encoded], -1)

    def step(self, robot, humans, mask, h, start):
        """Action mean (B, 2), value (B,) and the next recurrent state (the trainer's interface).

        The state is the scans the next step reads as its earlier ones.
        """
        scans = self._history(self._scan(robot), h, start)
        x = self.features(robot, scans)
        return self.actor(x), self.critic(x).squeeze(-1), self._next_state(scans, h)

    def sequence(self, robot, humans, mask, h0, starts):
        """Means (T, B, 2) and values (T, B) of T steps of B episodes.

        The scan history is rebuilt step by step from h0, as ``step`` builds it.
        """
        t, b = robot.shape[:2]
        scan = self._scan(robot)
        if self.lidar_history == 1:
            scans = scan.reshape(t * b, 1, -1)
        else:
            h, stacked = h0, []
            for i in range(t):
                s_i = self._history(scan[i], h, starts[i])
                stacked.append(s_i)
                h = self._next_state(s_i, h)
            scans = torch.stack(stacked).reshape(t * b, self.lidar_history, -1)
        x = self.features(robot.reshape(t * b, -1), scans)
        return self.actor(x).view(t, b, 2), self.critic(x).view(t, b)
