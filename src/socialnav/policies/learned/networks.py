"""The learned networks: each learned policy's network by name, and the value networks' building blocks.

:data:`LEARNED_POLICIES` and :func:`build` read the network factories from the registration records
(:mod:`socialnav.policies.learned_catalog`); ``build(name, **kw)`` makes a fresh, randomly initialised
network (seed torch beforehand). The building blocks shared by the value networks: MLPs, masking, the
network base class.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence

import torch
from torch import nn

from socialnav.policies.learned.state import SELF_DIM
from socialnav.policies.learned_catalog import get_learned_spec, learned_policy_names

__all__ = [
    "LEARNED_POLICIES", "build", "mlp", "ValueNetwork", "masked_softmax", "masked_mean", "self_state_of",
]


class _NetworkFactories(Mapping[str, Callable[..., nn.Module]]):
    """Policy name (aliases included) → network factory, a live view of the registration records."""

    def __getitem__(self, name: str) -> Callable[..., nn.Module]:
        if name not in learned_policy_names():
            raise KeyError(name)
        return get_learned_spec(name).network_factory()

    def __iter__(self) -> Iterator[str]:
        return iter(learned_policy_names())

    def __len__(self) -> int:
        return len(learned_policy_names())


LEARNED_POLICIES: Mapping[str, Callable[..., nn.Module]] = _NetworkFactories()


def build(name: str, **kwargs: object) -> nn.Module:
    """Build a fresh network by policy name.

    Args:
        name: a learned policy's name or alias (``learned_policy_names()`` of
            :mod:`socialnav.policies.learned_catalog`).
        **kwargs: keyword arguments of the network's constructor.

    Raises:
        KeyError: unknown name (the message lists the known ones).
    """
    return get_learned_spec(name).network_factory()(**kwargs)


def mlp(input_dim: int, dims: Sequence[int], last_relu: bool = False) -> nn.Sequential:
    """Linear layers of widths ``dims`` with ReLU between them (and after the last if ``last_relu``)."""
    layers: list[nn.Module] = []
    prev = input_dim
    for i, d in enumerate(dims):
        layers.append(nn.Linear(prev, d))
        if i < len(dims) - 1 or last_relu:
            layers.append(nn.ReLU(inplace=True))
        prev = d
    return nn.Sequential(*layers)


def masked_softmax(scores: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Softmax over the last dim restricted to ``mask``; rows with no True give all-zero weights.

    Numerically stable: the max over real entries is subtracted; masked entries are filled with -inf
    before exponentiation, so garbage (even NaN/inf) in masked entries cannot leak.

    Args:
        scores: (…, N) scores.
        mask: (…, N) bool.

    Returns:
        (…, N) weights summing to 1 over real entries (0 for rows without any).
    """
    s = scores.masked_fill(~mask, float("-inf"))
    mx = s.amax(dim=-1, keepdim=True)
    mx = torch.where(torch.isfinite(mx), mx, torch.zeros_like(mx))
    ex = torch.exp(s - mx)
    den = ex.sum(dim=-1, keepdim=True)
    return torch.where(den > 0, ex / den.clamp_min(torch.finfo(ex.dtype).tiny), torch.zeros_like(ex))


def masked_mean(x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Mean of (M, N, F) over N restricted to (M, N) ``mask``; 0 where no entry is real. → (M, F)."""
    m = mask.to(x.dtype).unsqueeze(1)  # (M, 1, N)
    return torch.bmm(m, x).squeeze(1) / m.sum(dim=2).clamp_min(1.0)


def self_state_of(joint: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Robot part (first 6 columns) of the joint state, read from the first real human's row.

    Every row of a joint state built by :func:`~socialnav.policies.learned.state.rotate` carries the same
    robot part; reading it from a real row keeps garbage in padded rows out. Rows with no real human
    read slot 0, which must then hold the robot part (``rotate`` guarantees it).

    Args:
        joint: (M, N, D) joint states, N ≥ 1.
        mask: (M, N) bool.

    Returns:
        (M, 6).
    """
    first = mask.to(torch.uint8).argmax(dim=1)  # 0 when no real human
    idx = first.view(-1, 1, 1).expand(-1, 1, SELF_DIM)
    return joint[..., :SELF_DIM].gather(1, idx).squeeze(1)


class ValueNetwork(nn.Module):
    """Base class: ``value(joint_state (M, N, D), mask (M, N)) -> (M,)``.

    Subclasses set ``name`` (registry name stored in checkpoints), ``input_dim`` (D), ``with_om``
    (whether the per-human input carries an occupancy map after the 13 joint-state values) and
    implement ``_value`` on inputs whose padded rows have been zeroed. ``model_kwargs()`` returns the
    constructor arguments (saved in checkpoints to rebuild the network).
    """

    name: str = ""
    input_dim: int = 13
    with_om: bool = False

    def model_kwargs(self) -> dict[str, object]:  # pragma: no cover - overridden
        """The constructor's keyword arguments, saved with the checkpoint to rebuild the network."""
        raise NotImplementedError

    def value(self, joint_state: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """State values.

        Args:
            joint_state: (M, N, D) agent-centric joint states (D = ``input_dim``), N ≥ 1.
            mask: (M, N) bool, real humans. Padded rows never influence the result; a row with no
                real human is valued from the robot state with a zero human feature vector.

        Returns:
            (M,) values.
        """
        if joint_state.dim() != 3 or joint_state.shape[-1] != self.input_dim:
            raise ValueError(
                f"{self.name}: expected joint state (M, N, {self.input_dim}), got {tuple(joint_state.shape)}"
            )
        if joint_state.shape[1] == 0:
            raise ValueError(f"{self.name}: N must be ≥ 1 (pad with one masked human)")
        mask = mask.to(torch.bool)
        self_state = self_state_of(joint_state, mask)
        joint = joint_state.masked_fill(~mask.unsqueeze(-1), 0.0)
        return self._value(self_state, joint, mask)

    def forward(self, joint_state: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """State values (M,) of joint states (M, N, D) with mask (M, N): the same as :meth:`value`."""
        return self.value(joint_state, mask)

    def _value(self, self_state: torch.Tensor, joint: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        raise NotImplementedError
