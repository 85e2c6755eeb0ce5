"""Relational graph over the robot and its humans (the building block of RGL).

Reference: C. Chen, S. Hu, P. Nikdel, G. Mori, M. Savva, "Relational Graph Learning for Crowd
Navigation", IROS 2020 — implemented from the paper's description:

    X  = [x_r; x_1; …; x_N]            node features: embedded robot state, embedded human states
    A  = row-softmax(X W_a Xᵀ)          relation matrix (embedded-Gaussian similarity)
    H⁰ = X,  Hˡ⁺¹ = ReLU(A Hˡ Wˡ) + Hˡ   graph convolutions with skip connections

Padded humans (mask False) are excluded from every softmax row (their columns get weight 0), so they
never influence a real node; the robot node is always present, so zero humans is fine (A = [1]).

Initialisation: the original code draws W_a with an unscaled ``randn`` (entries of variance 1, which
for 32-wide embeddings saturates the softmax at the start of training). Here W_a and every Wˡ use
Xavier/Glorot uniform initialisation (variance 2/(fan_in + fan_out)) and the MLPs PyTorch's default
(Kaiming-uniform) — see docs/policies_learned.md.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn

from socialnav.policies.learned.networks import masked_softmax, mlp

__all__ = ["RelationalGraph"]


class RelationalGraph(nn.Module):
    """Robot/human embeddings, relation matrix and graph convolutions.

    Args:
        robot_dim: robot feature size (6: the robot part of the joint state).
        human_dim: human feature size (7: the human part of the joint state).
        robot_dims, human_dims: embedding MLP widths (the last is the node feature size X_dim).
        layers: number of graph-convolution layers.
    """

    def __init__(
        self,
        robot_dim: int,
        human_dim: int,
        robot_dims: Sequence[int] = (64, 32),
        human_dims: Sequence[int] = (64, 32),
        layers: int = 2,
    ) -> None:
        super().__init__()
        if robot_dims[-1] != human_dims[-1]:
            raise ValueError(
                "robot and human embeddings must have the same width, "
                f"got {robot_dims[-1]} and {human_dims[-1]}"
            )
        self.x_dim = int(robot_dims[-1])
        self.robot_embed = mlp(robot_dim, robot_dims, last_relu=True)
        self.human_embed = mlp(human_dim, human_dims, last_relu=True)
        self.w_a = nn.Parameter(torch.empty(self.x_dim, self.x_dim))
        self.convs = nn.ModuleList(nn.Linear(self.x_dim, self.x_dim, bias=False) for _ in range(layers))
        nn.init.xavier_uniform_(self.w_a)
        for conv in self.convs:
            nn.init.xavier_uniform_(conv.weight)

    def nodes(self, robot: torch.Tensor, humans: torch.Tensor) -> torch.Tensor:
        """Node features X (M, 1 + N, x_dim) from robot (M, robot_dim) and humans (M, N, human_dim)."""
        m, n, d = humans.shape
        xr = self.robot_embed(robot).unsqueeze(1)
        xh = self.human_embed(humans.reshape(m * n, d)).view(m, n, -1)
        return torch.cat([xr, xh], dim=1)

    @staticmethod
    def node_mask(mask: torch.Tensor) -> torch.Tensor:
        """(M, 1 + N) bool: the robot node is always present."""
        return torch.cat([mask.new_ones(mask.shape[0], 1), mask], dim=1)

    def relation(self, x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """Relation matrix A (M, 1 + N, 1 + N): rows sum to 1 over present nodes, 0 on padded columns."""
        scores = torch.matmul(torch.matmul(x, self.w_a), x.transpose(1, 2))
        cols = self.node_mask(mask).unsqueeze(1).expand_as(scores)
        return masked_softmax(scores, cols)

    def forward(self, robot: torch.Tensor, humans: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """Node features after the graph convolutions, (M, 1 + N, x_dim); row 0 is the robot."""
        h = self.nodes(robot, humans)
        a = self.relation(h, mask)
        for conv in self.convs:
            h = torch.relu(torch.bmm(a, conv(h))) + h
        return h
