"""CADRL value network (pairwise), batched over episodes, actions and humans.

Reference: Y. F. Chen, M. Liu, M. Everett, J. P. How, "Decentralized Non-communicating Multiagent
Collision Avoidance with Deep Reinforcement Learning", ICRA 2017.

A pairwise value MLP 13 → 150 → 100 → 100 → 1 scores (robot, human_i); the state value is the minimum
over real humans (the most constraining neighbour), as the multi-agent extension of the paper does.
With no real human, the MLP is evaluated on the robot part with the 7 human values set to zero.
Trained with one human, as its authors did.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch

from socialnav.policies.learned.networks import ValueNetwork, mlp
from socialnav.policies.learned.state import JOINT_DIM, SELF_DIM

__all__ = ["CADRL"]


class CADRL(ValueNetwork):
    """Pairwise value network, min over humans.

    Args:
        input_dim: per-human joint-state size (13).
        mlp_dims: hidden and output widths.
    """

    name = "cadrl"

    def __init__(self, input_dim: int = JOINT_DIM, mlp_dims: Sequence[int] = (150, 100, 100, 1)) -> None:
        super().__init__()
        self.input_dim = int(input_dim)
        self.mlp_dims = tuple(int(d) for d in mlp_dims)
        self.value_mlp = mlp(self.input_dim, self.mlp_dims)

    def model_kwargs(self) -> dict[str, object]:
        """The constructor's keyword arguments, saved with the checkpoint to rebuild the network."""
        return {"input_dim": self.input_dim, "mlp_dims": list(self.mlp_dims)}

    def _value(self, self_state: torch.Tensor, joint: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        m, n, d = joint.shape
        v = self.value_mlp(joint.reshape(m * n, d)).view(m, n)
        v = v.masked_fill(~mask, float("inf")).amin(dim=1)
        empty = ~mask.any(dim=1)
        if bool(empty.any()):
            alone = torch.zeros(int(empty.sum()), d, dtype=joint.dtype, device=joint.device)
            alone[:, :SELF_DIM] = self_state[empty]
            v = v.masked_scatter(empty, self.value_mlp(alone).view(-1))
        return v
