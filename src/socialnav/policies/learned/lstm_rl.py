"""LSTM value network in the spirit of GA3C-CADRL (CrowdNav's "LSTM-RL").

Reference: M. Everett, Y. F. Chen, J. P. How, "Motion Planning Among Dynamic, Decision-Making Agents
with Deep Reinforcement Learning", IROS 2018 (GA3C-CADRL). The original is an A3C policy-gradient
network; this is the value-based stand-in that CrowdNav (Chen et al., ICRA 2019) calls LSTM-RL: it
shares GA3C-CADRL's idea of encoding a variable number of humans with an LSTM fed by humans sorted by
decreasing distance (closest last), and is trained and used as a value network with one-step
lookahead like the other baselines here.

Architecture: optional per-human MLP 13 → 150 → 100 → 100 → 50 (``with_interaction_module``), an LSTM
(hidden 50) over humans sorted by decreasing distance ``da`` with padded humans removed by
``pack_padded_sequence`` (so the final hidden state is that after the closest real human), then
[robot state (6), h] → 150 → 100 → 100 → 1. With no real human, h = 0.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn
from torch.nn.utils.rnn import pack_padded_sequence

from socialnav.policies.learned.networks import ValueNetwork, mlp
from socialnav.policies.learned.state import JOINT_DIM, SELF_DIM

__all__ = ["LSTMRL"]

DA_COLUMN = 11  # robot-human distance in the 13-value joint state


class LSTMRL(ValueNetwork):
    """LSTM value network over distance-sorted humans.

    Args:
        input_dim: per-human input size (13).
        mlp1_dims: per-human MLP widths (used when ``with_interaction_module``).
        lstm_hidden_dim: LSTM hidden size.
        mlp2_dims: value MLP widths after [robot state, h].
        with_interaction_module: feed the LSTM the per-human MLP features (True) or the raw 13 values.
    """

    name = "lstm_rl"

    def __init__(
        self,
        input_dim: int = JOINT_DIM,
        mlp1_dims: Sequence[int] = (150, 100, 100, 50),
        lstm_hidden_dim: int = 50,
        mlp2_dims: Sequence[int] = (150, 100, 100, 1),
        with_interaction_module: bool = True,
    ) -> None:
        super().__init__()
        self.input_dim = int(input_dim)
        self.mlp1_dims = tuple(int(d) for d in mlp1_dims)
        self.lstm_hidden_dim = int(lstm_hidden_dim)
        self.mlp2_dims = tuple(int(d) for d in mlp2_dims)
        self.with_interaction_module = bool(with_interaction_module)
        if self.with_interaction_module:
            self.mlp1 = mlp(self.input_dim, self.mlp1_dims)
            lstm_in = self.mlp1_dims[-1]
        else:
            self.mlp1 = nn.Identity()
            lstm_in = self.input_dim
        self.lstm = nn.LSTM(lstm_in, self.lstm_hidden_dim, batch_first=True)
        self.mlp2 = mlp(SELF_DIM + self.lstm_hidden_dim, self.mlp2_dims)

    def model_kwargs(self) -> dict[str, object]:
        """The constructor's keyword arguments, saved with the checkpoint to rebuild the network."""
        return {
            "input_dim": self.input_dim,
            "mlp1_dims": list(self.mlp1_dims),
            "lstm_hidden_dim": self.lstm_hidden_dim,
            "mlp2_dims": list(self.mlp2_dims),
            "with_interaction_module": self.with_interaction_module,
        }

    def _value(self, self_state: torch.Tensor, joint: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        m, n, d = joint.shape
        # Real humans first, by decreasing distance (closest last); padded humans after them.
        key = joint[..., DA_COLUMN].masked_fill(~mask, float("-inf"))
        order = torch.sort(key, dim=1, descending=True, stable=True).indices
        x = joint.gather(1, order.unsqueeze(-1).expand(m, n, d))
        x = self.mlp1(x.reshape(m * n, d)).view(m, n, -1)
        lengths = mask.sum(dim=1)
        packed = pack_padded_sequence(x, lengths.clamp_min(1).cpu(), batch_first=True, enforce_sorted=False)
        _, (h, _) = self.lstm(packed)
        h = h[-1] * (lengths > 0).to(x.dtype).unsqueeze(-1)  # no human → zero feature vector
        return self.mlp2(torch.cat([self_state, h], dim=1)).squeeze(-1)
