"""Learned human-motion predictor: a relational graph plus a motion head (RGL's state predictor).

Reference: C. Chen, S. Hu, P. Nikdel, G. Mori, M. Savva, "Relational Graph Learning for Crowd
Navigation", IROS 2020 (the "state prediction model": a second relational graph over the robot and
the humans, followed by a motion-prediction MLP that outputs each human's next position; trained by
MSE on observed human transitions). Implemented from that description.

Frame and parametrisation (decisions recorded in docs/policies_learned.md):
- Features are agent-centric (the joint state of :func:`~socialnav.policies.learned.state.rotate`:
  x-axis from the robot towards its goal), so the predictor is invariant to translations and
  rotations of the whole scene.
- The motion head outputs, per human, a velocity *correction* in that frame; the predicted
  displacement is (v_i + Δv_i)·dt. A crowd that keeps its velocity is therefore predicted exactly by
  Δv = 0, and the network only has to learn how people deviate from constant velocity.
- The predicted next velocity is the predicted displacement over dt (what an observer of the next
  position would measure); the radius is unchanged. Padded humans are returned unchanged.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn

from socialnav.policies.learned.graph import RelationalGraph
from socialnav.policies.learned.networks import mlp
from socialnav.policies.learned.state import SELF_DIM, rotate

__all__ = ["StatePredictor", "PREDICTOR_FORMAT"]

PREDICTOR_FORMAT = "socialnav.predictor/1"


class StatePredictor(nn.Module):
    """Predicts the humans' next observable states from the current robot and human states.

    Args:
        robot_dims, human_dims: node embedding widths of the graph.
        graph_layers: graph-convolution layers.
        motion_dims: motion-head widths (the last must be 2: a velocity correction).
    """

    def __init__(
        self,
        robot_dims: Sequence[int] = (64, 32),
        human_dims: Sequence[int] = (64, 32),
        graph_layers: int = 2,
        motion_dims: Sequence[int] = (64, 2),
    ) -> None:
        super().__init__()
        if int(motion_dims[-1]) != 2:
            raise ValueError(f"the motion head must end in 2 outputs (a velocity), got {motion_dims[-1]}")
        self.robot_dims = tuple(int(d) for d in robot_dims)
        self.human_dims = tuple(int(d) for d in human_dims)
        self.graph_layers = int(graph_layers)
        self.motion_dims = tuple(int(d) for d in motion_dims)
        self.graph = RelationalGraph(SELF_DIM, 7, self.robot_dims, self.human_dims, self.graph_layers)
        self.motion = mlp(self.graph.x_dim, self.motion_dims)
        # Start at the constant-velocity prediction: the last layer outputs zero corrections.
        last = self.motion[-1]
        assert isinstance(last, nn.Linear)
        nn.init.zeros_(last.weight)
        nn.init.zeros_(last.bias)

    def model_kwargs(self) -> dict[str, object]:
        """The constructor's keyword arguments, saved with the checkpoint to rebuild the network."""
        return {
            "robot_dims": list(self.robot_dims),
            "human_dims": list(self.human_dims),
            "graph_layers": self.graph_layers,
            "motion_dims": list(self.motion_dims),
        }

    def forward(
        self, robot: torch.Tensor, humans: torch.Tensor, mask: torch.Tensor, dt: float
    ) -> torch.Tensor:
        """Next human states.

        Args:
            robot: (M, 9) robot full states (px, py, vx, vy, radius, gx, gy, v_pref, theta).
            humans: (M, N, 5) human observable states (px, py, vx, vy, radius).
            mask: (M, N) bool, real humans.
            dt: time step [s].

        Returns:
            (M, N, 5) predicted next states, in the dtype of ``humans``.
        """
        mask = mask.to(torch.bool)
        if humans.shape[1] == 0:
            return humans.clone()
        dtype = next(self.parameters()).dtype
        joint = rotate(robot, humans, dtype=dtype)  # (M, N, 13), the robot part repeated per human
        joint = joint.masked_fill(~mask.unsqueeze(-1), 0.0)
        robot_part = rotate(robot, humans[:, :1], dtype=dtype)[:, 0, :SELF_DIM]
        h = self.graph(robot_part, joint[..., SELF_DIM:], mask)[:, 1:]  # human nodes (M, N, x)
        dv = self.motion(h).to(humans.dtype)  # (M, N, 2) in the robot-goal frame
        gx = robot[:, 5] - robot[:, 0]
        gy = robot[:, 6] - robot[:, 1]
        rot = torch.atan2(gy, gx).unsqueeze(1)
        c, s = torch.cos(rot), torch.sin(rot)
        dvx = dv[..., 0] * c - dv[..., 1] * s  # back to the world frame
        dvy = dv[..., 0] * s + dv[..., 1] * c
        vx = humans[..., 2] + dvx
        vy = humans[..., 3] + dvy
        out = humans.clone()
        out[..., 0] = humans[..., 0] + vx * dt
        out[..., 1] = humans[..., 1] + vy * dt
        out[..., 2] = vx
        out[..., 3] = vy
        return torch.where(mask.unsqueeze(-1), out, humans)

    def loss(
        self,
        robot: torch.Tensor,
        humans: torch.Tensor,
        mask: torch.Tensor,
        next_humans: torch.Tensor,
        next_mask: torch.Tensor,
        dt: float,
    ) -> torch.Tensor:
        """MSE of the predicted next positions [m²] over humans present in both states."""
        pred = self.forward(robot, humans, mask, dt)
        both = (mask.to(torch.bool) & next_mask.to(torch.bool)).to(pred.dtype)
        err = ((pred[..., :2] - next_humans[..., :2].to(pred.dtype)) ** 2).sum(-1)
        return (err * both).sum() / (2.0 * both.sum().clamp_min(1.0))
