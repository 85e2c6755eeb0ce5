"""A plain MLP actor-critic for PPO (``ppo_mlp``): the reference point for what the attention graph adds.

The input is the robot's features and the ``max_humans`` nearest real humans' features (the same
features as ``crowdnav_pp``'s, constant-velocity prediction included), nearest first, each with a flag
saying whether the slot holds a human; with fewer humans the remaining slots are zero, with more the
farthest are left out. Actor and critic are separate two-layer tanh MLPs (CleanRL's continuous-action
PPO agent); no recurrence, so the trainer's recurrent state is a dummy that the network passes through.

Among walls (``obstacle_slots`` K > 0) the last K slots of the input are the obstacle points of
:mod:`socialnav.sim.obstacle_points` (already nearest first, each with its flag). They get K input
slots of their own after the humans' instead of competing for the ``max_humans`` nearest slots, so
that a wall beside the robot never pushes a person out of its input.
"""

from __future__ import annotations

import torch
from torch import nn

from socialnav.policies.learned.attn_graph import ROBOT_FEATURES, ObservationStatistics, _init

__all__ = ["MLPActorCritic", "actor_critic_mlps"]


def actor_critic_mlps(width: int, hidden: int) -> tuple[nn.Sequential, nn.Sequential]:
    """CleanRL's separate actor (2 outputs, gain 0.01) and critic (1 output) tanh MLPs over ``width`` inputs.

    Built actor first, so a seeded initialisation gives the same weights wherever it is used.
    """

    def mlp(out: int, gain: float) -> nn.Sequential:
        return nn.Sequential(
            _init(nn.Linear(width, hidden)),
            nn.Tanh(),
            _init(nn.Linear(hidden, hidden)),
            nn.Tanh(),
            _init(nn.Linear(hidden, out), gain),
        )

    return mlp(2, 0.01), mlp(1, 1.0)


class MLPActorCritic(ObservationStatistics):
    """MLP actor-critic over the robot and the ``max_humans`` nearest humans (module docstring)."""

    gru_hidden = 1  # the trainer's recurrent state: unused

    def __init__(
        self,
        prediction_steps: int = 5,
        max_humans: int = 5,
        hidden: int = 256,
        normalize_obs: bool = True,
        log_std_init: float = 0.0,
        obstacle_slots: int = 0,
    ) -> None:
        super().__init__()
        if prediction_steps < 0 or max_humans < 0 or hidden < 1 or obstacle_slots < 0:
            raise ValueError(
                f"prediction_steps, max_humans and obstacle_slots must be >= 0 and hidden >= 1, got "
                f"{prediction_steps}, {max_humans}, {obstacle_slots}, {hidden}"
            )
        self._kwargs = dict(
            prediction_steps=prediction_steps,
            max_humans=max_humans,
            hidden=hidden,
            normalize_obs=normalize_obs,
            log_std_init=log_std_init,
        )
        if obstacle_slots:  # recorded only among walls: open-floor checkpoints keep their bytes
            self._kwargs["obstacle_slots"] = obstacle_slots
        self.prediction_steps, self.max_humans = prediction_steps, max_humans
        self.obstacle_slots = obstacle_slots
        self.input_dim = 2 * (1 + prediction_steps)
        self.normalize_obs = normalize_obs
        width = ROBOT_FEATURES + (max_humans + obstacle_slots) * (self.input_dim + 1)
        self.actor, self.critic = actor_critic_mlps(width, hidden)
        self.log_std = nn.Parameter(torch.full((2,), float(log_std_init)))
        self._init_obs_stats()

    def model_kwargs(self) -> dict:
        """The constructor's keyword arguments, saved with the checkpoint to rebuild the network."""
        return dict(self._kwargs)

    def initial_state(self, batch: int, device: torch.device | str = "cpu") -> torch.Tensor:
        """A placeholder recurrent state, (batch, 1) zeros: the MLP keeps none between steps."""
        return torch.zeros(batch, 1, device=device)

    def flat_input(self, robot: torch.Tensor, humans: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """(M, width): normalised robot features, the nearest humans' features and flags, then the points'.

        Raises:
            ValueError: fewer slots than the network's ``obstacle_slots``.
        """
        robot_n, humans_n = self._normalized(robot, humans)
        p = self.obstacle_slots
        if not p:
            return torch.cat([robot_n, self._nearest_slots(humans, humans_n, mask)], -1)
        n = humans.shape[1] - p
        if n < 0:
            total = humans.shape[1]
            raise ValueError(f"the network reads {p} point slots, the input has {total} slots in all")
        points = torch.cat([humans_n[:, n:], torch.ones_like(humans_n[:, n:, :1])], -1)
        points = points * mask[:, n:, None].to(points.dtype)
        nearest = self._nearest_slots(humans[:, :n], humans_n[:, :n], mask[:, :n])
        return torch.cat([robot_n, nearest, points.flatten(1)], -1)

    def _nearest_slots(self, humans: torch.Tensor, humans_n: torch.Tensor, mask: torch.Tensor
                       ) -> torch.Tensor:
        """(M, max_humans·(input_dim + 1)): the nearest real humans' normalised features and flags."""
        m, k = humans.shape[0], self.max_humans
        if humans.shape[1] == 0 or k == 0:
            return humans.new_zeros(m, k * (self.input_dim + 1))
        # distance of each slot now (the first two raw features: position relative to the robot)
        dist = torch.linalg.vector_norm(humans[..., 0:2], dim=-1).masked_fill(~mask, float("inf"))
        order = torch.argsort(dist, dim=1, stable=True)[:, :k]
        picked = torch.gather(humans_n, 1, order[..., None].expand(-1, -1, self.input_dim))
        flag = torch.gather(mask, 1, order)
        slots = torch.cat([picked, torch.ones_like(picked[..., :1])], -1) * flag[..., None].to(picked.dtype)
        if slots.shape[1] < k:  # fewer slots than max_humans: zero padding
            slots = torch.cat([slots, slots.new_zeros(m, k - slots.shape[1], slots.shape[2])], 1)
        return slots.flatten(1)

    def step(self, robot, humans, mask, h, start):
        """Action mean (B, 2), value (B,) and the unchanged dummy state (the trainer's interface)."""
        x = self.flat_input(robot, humans, mask)
        return self.actor(x), self.critic(x).squeeze(-1), h

    def sequence(self, robot, humans, mask, h0, starts):
        """Means (T, B, 2) and values (T, B) of T steps of B episodes (no recurrence)."""
        t, b = robot.shape[:2]
        x = self.flat_input(
            robot.reshape(t * b, -1), humans.reshape(t * b, *humans.shape[2:]), mask.reshape(t * b, -1)
        )
        return self.actor(x).view(t, b, 2), self.critic(x).view(t, b)
