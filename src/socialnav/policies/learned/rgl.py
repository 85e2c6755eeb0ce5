"""RGL value network (relational graph learning) and its model-predictive variant's registry entry.

Reference: C. Chen, S. Hu, P. Nikdel, G. Mori, M. Savva, "Relational Graph Learning for Crowd
Navigation", IROS 2020.

Input: the 13-value agent-centric joint state per human (robot part: 6 values, human part: 7). The
robot node embeds the robot part (6 → 64 → 32), each human node its human part (7 → 64 → 32); a
relational graph (:class:`~socialnav.policies.learned.graph.RelationalGraph`: relation matrix by
embedded-Gaussian similarity with a row softmax, two graph convolutions with skip connections)
mixes them, and the value MLP reads the robot node: 32 → 150 → 100 → 100 → 1.

``mp_rgl`` is the same value network; what makes it model-predictive is how
:class:`~socialnav.policies.learned.value_policy.ValuePolicy` uses it: with the learned state
predictor (:mod:`socialnav.policies.learned.predictor`) and d-step, w-wide planning.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch

from socialnav.policies.learned.graph import RelationalGraph
from socialnav.policies.learned.networks import ValueNetwork, mlp, self_state_of
from socialnav.policies.learned.state import JOINT_DIM, SELF_DIM

__all__ = ["RGL", "mp_rgl"]


class RGL(ValueNetwork):
    """Relational-graph value network.

    Args:
        input_dim: per-human joint-state size (13).
        robot_dims, human_dims: node embedding widths (the last is the node feature size).
        graph_layers: graph-convolution layers.
        value_dims: value MLP widths on the robot node.
    """

    name = "rgl"

    def __init__(
        self,
        input_dim: int = JOINT_DIM,
        robot_dims: Sequence[int] = (64, 32),
        human_dims: Sequence[int] = (64, 32),
        graph_layers: int = 2,
        value_dims: Sequence[int] = (150, 100, 100, 1),
    ) -> None:
        super().__init__()
        self.input_dim = int(input_dim)
        self.robot_dims = tuple(int(d) for d in robot_dims)
        self.human_dims = tuple(int(d) for d in human_dims)
        self.graph_layers = int(graph_layers)
        self.value_dims = tuple(int(d) for d in value_dims)
        self.graph = RelationalGraph(
            SELF_DIM, self.input_dim - SELF_DIM, self.robot_dims, self.human_dims, self.graph_layers
        )
        self.value_mlp = mlp(self.graph.x_dim, self.value_dims)

    def model_kwargs(self) -> dict[str, object]:
        """The constructor's keyword arguments, saved with the checkpoint to rebuild the network."""
        return {
            "input_dim": self.input_dim,
            "robot_dims": list(self.robot_dims),
            "human_dims": list(self.human_dims),
            "graph_layers": self.graph_layers,
            "value_dims": list(self.value_dims),
        }

    @torch.no_grad()
    def relation_matrix(self, joint_state: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """Relation matrix (M, 1 + N, 1 + N) of joint states (node 0 is the robot); for inspection."""
        mask = mask.to(torch.bool)
        self_state = self_state_of(joint_state, mask)
        joint = joint_state.masked_fill(~mask.unsqueeze(-1), 0.0)
        x = self.graph.nodes(self_state, joint[..., SELF_DIM:])
        return self.graph.relation(x, mask)

    def _value(self, self_state: torch.Tensor, joint: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        h = self.graph(self_state, joint[..., SELF_DIM:], mask)
        return self.value_mlp(h[:, 0]).squeeze(-1)


def mp_rgl(**kwargs: object) -> RGL:
    """Model-predictive RGL: the RGL value network, planned with the learned state predictor."""
    net = RGL(**kwargs)  # type: ignore[arg-type]
    net.name = "mp_rgl"
    return net
