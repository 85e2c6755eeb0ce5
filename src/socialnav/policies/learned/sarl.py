"""SARL and OM-SARL value networks (socially attentive RL).

Reference: C. Chen, Y. Liu, S. Kreiss, A. Alahi, "Crowd-Robot Interaction: Crowd-aware Robot Navigation
with Attention-based Deep Reinforcement Learning", ICRA 2019.

Per human i (input: the 13-value joint state, or 13 + 48 with the local occupancy map for OM-SARL):
    e_i = mlp1(x_i)            13 (61) → 150 → 100, ReLU after the last layer kept
    h_i = mlp2(e_i)            100 → 100 → 50
    g   = masked mean_j e_j    (100)
    s_i = attention([e_i, g])  200 → 100 → 100 → 1
    w   = masked softmax_i(s)  (numerically stable; zero weights when no human is real)
    V   = mlp3([robot state (6), Σ_i w_i h_i])  56 → 150 → 100 → 100 → 1
With no real human the weighted sum is the zero vector, so V comes from the robot state alone.

The first attention layer is an ordinary ``nn.Linear(200, 100)``; it is evaluated as
``W[:, :100] e_i + W[:, 100:] g + b`` so the global term is computed once per state instead of once
per human, and the e-half is fused with mlp2's first layer into one 100 → 200 matmul (same function,
same parameters, fewer FLOPs and fewer passes over memory).
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn

from socialnav.policies.learned.networks import ValueNetwork, masked_mean, masked_softmax, mlp
from socialnav.policies.learned.state import JOINT_DIM, OM_DIM, SELF_DIM

__all__ = ["SARL", "om_sarl"]


class SARL(ValueNetwork):
    """SARL value network; ``with_om=True`` gives OM-SARL.

    Args:
        input_dim: per-human input size; default 13, or 13 + ``om_dim`` when ``with_om``.
        mlp1_dims, mlp2_dims, attention_dims, mlp3_dims: layer widths (CrowdNav's).
        with_global_state: feed the attention MLP [e_i, mean_j e_j] (True) or e_i alone.
        with_om: the per-human input carries a local occupancy map (OM-SARL).
        om_dim: occupancy-map size (cell_num² · channels; 48 by default).
    """

    name = "sarl"

    def __init__(
        self,
        input_dim: int | None = None,
        mlp1_dims: Sequence[int] = (150, 100),
        mlp2_dims: Sequence[int] = (100, 50),
        attention_dims: Sequence[int] = (100, 100, 1),
        mlp3_dims: Sequence[int] = (150, 100, 100, 1),
        with_global_state: bool = True,
        with_om: bool = False,
        om_dim: int = OM_DIM,
    ) -> None:
        super().__init__()
        self.with_om = bool(with_om)
        self.om_dim = int(om_dim)
        if self.with_om:
            self.name = "om_sarl"
        default_dim = JOINT_DIM + (self.om_dim if self.with_om else 0)
        self.input_dim = int(input_dim) if input_dim is not None else default_dim
        self.mlp1_dims = tuple(int(d) for d in mlp1_dims)
        self.mlp2_dims = tuple(int(d) for d in mlp2_dims)
        self.attention_dims = tuple(int(d) for d in attention_dims)
        self.mlp3_dims = tuple(int(d) for d in mlp3_dims)
        self.with_global_state = bool(with_global_state)
        e_dim = self.mlp1_dims[-1]
        self.mlp1 = mlp(self.input_dim, self.mlp1_dims, last_relu=True)
        self.mlp2 = mlp(e_dim, self.mlp2_dims)
        self.attention = mlp(2 * e_dim if self.with_global_state else e_dim, self.attention_dims)
        self.mlp3 = mlp(SELF_DIM + self.mlp2_dims[-1], self.mlp3_dims)

    def model_kwargs(self) -> dict[str, object]:
        """The constructor's keyword arguments, saved with the checkpoint to rebuild the network."""
        return {
            "input_dim": self.input_dim,
            "mlp1_dims": list(self.mlp1_dims),
            "mlp2_dims": list(self.mlp2_dims),
            "attention_dims": list(self.attention_dims),
            "mlp3_dims": list(self.mlp3_dims),
            "with_global_state": self.with_global_state,
            "with_om": self.with_om,
            "om_dim": self.om_dim,
        }

    def _global_term(self, e: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """Global-state half of the first attention layer plus its bias: W_g · mean_j e_j + b → (M, 100)."""
        first = self.attention[0]
        assert isinstance(first, nn.Linear)
        k = e.shape[-1]
        g = masked_mean(e, mask)  # (M, k)
        return torch.addmm(first.bias, g, first.weight[:, k:].t())

    def attention_scores(self, e: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """Unnormalised attention scores (M, N) from per-human embeddings e (M, N, 100)."""
        m, n, k = e.shape
        first = self.attention[0]
        assert isinstance(first, nn.Linear)
        if self.with_global_state:
            a = torch.matmul(e, first.weight[:, :k].t()) + self._global_term(e, mask).unsqueeze(1)
        else:
            a = first(e)
        return self.attention[1:](a.view(m * n, -1)).view(m, n)

    def attention_weights(self, joint_state: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """Attention weights (M, N) over humans (0 on padded humans); for inspection and plots."""
        mask = mask.to(torch.bool)
        joint = joint_state.masked_fill(~mask.unsqueeze(-1), 0.0)
        m, n, d = joint.shape
        e = self.mlp1(joint.reshape(m * n, d)).view(m, n, -1)
        return masked_softmax(self.attention_scores(e, mask), mask)

    def _value(self, self_state: torch.Tensor, joint: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        m, n, d = joint.shape
        e = self.mlp1(joint.reshape(m * n, d))  # (M·N, 100)
        if self.with_global_state:
            # mlp2's first layer and the e-half of the attention's first layer read the same e: one
            # (M·N, 100) @ (100, 100 + 100) matmul instead of two.
            l2, la = self.mlp2[0], self.attention[0]
            assert isinstance(l2, nn.Linear) and isinstance(la, nn.Linear)
            k, d2 = e.shape[1], l2.out_features
            y = torch.addmm(
                torch.cat([l2.bias, la.bias.new_zeros(la.out_features)]),
                e,
                torch.cat([l2.weight, la.weight[:, :k]], dim=0).t(),
            )
            a = y[:, d2:].view(m, n, -1) + self._global_term(e.view(m, n, k), mask).unsqueeze(1)
            scores = self.attention[1:](a.view(m * n, -1)).view(m, n)
            h = self.mlp2[1:](y[:, :d2])
        else:
            h = self.mlp2(e)
            scores = self.attention(e).view(m, n)
        w = masked_softmax(scores, mask)  # (M, N)
        feat = torch.bmm(w.unsqueeze(1), h.view(m, n, -1)).squeeze(1)  # (M, 50)
        return self.mlp3(torch.cat([self_state, feat], dim=1)).squeeze(-1)


def om_sarl(**kwargs: object) -> SARL:
    """OM-SARL: SARL whose per-human input is the 13 joint-state values + a 4×4×3 occupancy map (61)."""
    kwargs.pop("with_om", None)
    return SARL(with_om=True, **kwargs)  # type: ignore[arg-type]
