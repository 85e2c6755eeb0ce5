"""Native (C++) evaluation of SARL and OM-SARL value networks for batched action scoring.

The PyTorch module (:class:`~socialnav.policies.learned.sarl.SARL`) stays the definition of the
network and the only path used in training; this evaluates the same function faster on a CPU. A
one-step lookahead scores B × 81 joint states per call; layer by layer, each of the network's
activations for a block of them goes through L3 or memory between two matmuls, which caps PyTorch's
chain of library matmuls well below the machine's matmul rate (docs/policies_learned.md,
"Benchmark"). The native scorer takes 32 states at a time through every layer while their activations
stay in L1/L2, with bias, ReLU and the global-state term applied in the matmul's registers.

Values: float32 with fused multiply-adds, each output summed in a fixed order, so a state's value
depends only on that state (identical for any batch size and thread count). They differ from
PyTorch's by float32 rounding (relative differences of order 1e-7 to 1e-6); an action can therefore
differ where two actions' values tie to that precision.

Kernels: an AVX2 + FMA kernel (16 columns, up to 6 rows per instruction block) and an AVX-512 one
(32 columns, up to 12 rows), chosen at run time from what the CPU supports (``auto``: the widest), or
forced with the ``kernel`` argument or the environment variable ``SOCIALNAV_SCORER_KERNEL``
(``auto``, ``avx2``, ``avx512``). Both compute each output with the same operations in the same order
(bias, then one fused multiply-add per input in index order), so their values are bit-identical
(tested); the kernel in effect is recorded in a run's manifest as ``policy.native_kernel`` for
information only: it never changes a result, so resuming or replaying a run on a CPU with the other
kernel is allowed.

SARL: C. Chen, Y. Liu, S. Kreiss, A. Alahi, "Crowd-Robot Interaction: Crowd-aware Robot Navigation
with Attention-based Deep Reinforcement Learning", ICRA 2019.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from socialnav.policies.learned.networks import ValueNetwork
from socialnav.policies.learned.sarl import SARL
from socialnav.policies.learned.state import SELF_DIM

__all__ = [
    "KERNELS",
    "SCORERS",
    "NativeSarlScorer",
    "ScorerError",
    "native_unavailable_reason",
]

SCORERS = ("auto", "torch", "native")
KERNELS = ("auto", "avx2", "avx512")
KERNEL_ENV = "SOCIALNAV_SCORER_KERNEL"
STATES_PER_TILE = 32


class ScorerError(ValueError):
    """An unknown scorer, or "native" where it cannot run: the caller's choice, not the network's."""


def native_unavailable_reason(network: ValueNetwork, device: torch.device) -> str | None:
    """Why the native scorer cannot evaluate ``network`` on ``device``; None when it can."""
    if not isinstance(network, SARL):
        return f"the native scorer evaluates SARL and OM-SARL only, not {network.name!r}"
    if device.type != "cpu":
        return f"the native scorer runs on the CPU, the policy on {device}"
    if any(p.device.type != "cpu" for p in network.parameters()):
        return "the native scorer runs on the CPU, the network's parameters are not on it"
    dtypes = {p.dtype for p in network.parameters()}
    if dtypes != {torch.float32}:
        return f"the native scorer needs float32 parameters, the network has {sorted(map(str, dtypes))}"
    for seq in (network.mlp1, network.mlp2, network.attention, network.mlp3):
        for module in seq:
            if not isinstance(module, (nn.Linear, nn.ReLU)) or (
                isinstance(module, nn.Linear) and module.bias is None
            ):
                return f"the native scorer supports Linear (with bias) and ReLU layers, not {module!r}"
    from socialnav import _core

    if not _core.SarlScorer.supported():
        return "this CPU lacks AVX2/FMA, which the native scorer's kernels need"
    return None


def _layers(seq: nn.Sequential) -> list[tuple[np.ndarray, np.ndarray]]:
    return [
        (m.weight.detach().contiguous().numpy(), m.bias.detach().contiguous().numpy())
        for m in seq
        if isinstance(m, nn.Linear)
    ]


def _attention_layers(
    net: SARL,
) -> tuple[list[tuple[np.ndarray, np.ndarray]], list[tuple[np.ndarray, np.ndarray]]]:
    """The attention MLP and its global term, as the native scorer takes them.

    With the global state, the first layer W [e_i, g] + b is split as in ``SARL.attention_scores``:
    the e-half per human (no bias) stays first in the MLP, the g-half with the bias is the global term.
    """
    attention = _layers(net.attention)
    if not net.with_global_state:
        return attention, []
    (w, b), k = attention[0], net.mlp1_dims[-1]
    e_half = (np.ascontiguousarray(w[:, :k]), np.zeros_like(b))
    return [e_half, *attention[1:]], [(np.ascontiguousarray(w[:, k:]), b)]


def requested_kernel(kernel: str | None = None) -> str:
    """The vector kernel asked for: ``kernel``, else ``$SOCIALNAV_SCORER_KERNEL``, else ``auto``.

    A :class:`ScorerError` names an unknown one or one this CPU cannot run.
    """
    import os

    from socialnav import _core

    name = kernel if kernel is not None else (os.environ.get(KERNEL_ENV) or "auto")
    where = "kernel" if kernel is not None else f"${KERNEL_ENV}"
    if name not in KERNELS:
        raise ScorerError(
            f"{where}: unknown native scorer kernel {name!r}; expected one of {', '.join(KERNELS)}"
        )
    if name != "auto" and not _core.SarlScorer.kernel_supported(name):
        raise ScorerError(f"{where}: this CPU cannot run the native scorer's {name} kernel")
    return name


class NativeSarlScorer:
    """``value(joint, mask)`` of a SARL / OM-SARL network, evaluated by the native core.

    The network's weights are packed once and packed again whenever a parameter changes (a training
    step, ``load_state_dict``), so the scorer always evaluates the network as it is now.

    Args:
        network: the SARL or OM-SARL network (float32, CPU).
        states_per_tile: joint states taken through all layers at a time (a multiple of 16).
        kernel: "auto", "avx2" or "avx512"; None reads ``$SOCIALNAV_SCORER_KERNEL`` (default auto).
    """

    def __init__(
        self, network: SARL, states_per_tile: int = STATES_PER_TILE, kernel: str | None = None
    ) -> None:
        self.network = network
        self.states_per_tile = int(states_per_tile)
        self.kernel_request = requested_kernel(kernel)
        # What was read from the network at its version `_seen` (parameters' storage, device, dtype and
        # in-place version counters): why it cannot be scored natively, or its packed weights (built
        # on first use). Both are dropped when the network changes.
        self._seen: tuple | None = None
        self._reason: str | None = None
        self._packed: object | None = None
        self._pool: object | None = None
        reason = self.unavailable_reason()
        if reason is not None:
            raise ValueError(reason)

    def __getstate__(self) -> dict:
        # The packed weights and the thread pool are native objects: rebuilt on first use after
        # unpickling (a policy is pickled into evaluation worker processes).
        state = dict(self.__dict__)
        state.update(_seen=None, _reason=None, _packed=None, _pool=None)
        return state

    def unavailable_reason(self) -> str | None:
        """None while the network can still be evaluated natively (re-checked when it changes)."""
        seen = tuple((p.data_ptr(), p.device, p.dtype, p._version) for p in self.network.parameters())
        if seen != self._seen:
            self._seen, self._packed = seen, None
            self._reason = native_unavailable_reason(self.network, torch.device("cpu"))
        return self._reason

    def _scorer(self):
        from socialnav import _core

        reason = self.unavailable_reason()
        if reason is not None:
            raise ValueError(reason)
        if self._packed is None:
            net = self.network
            attention, global_term = _attention_layers(net)
            self._packed = _core.SarlScorer(
                _layers(net.mlp1), _layers(net.mlp2), attention, global_term, _layers(net.mlp3), SELF_DIM,
                self.kernel_request,
            )
        return self._packed

    @property
    def kernel(self) -> str:
        """The vector kernel in effect: "avx2" or "avx512"."""
        return str(self._scorer().kernel)

    def _threads(self):
        from socialnav import _core

        n = max(1, torch.get_num_threads())  # the same budget as PyTorch's intra-op threads
        if self._pool is None or self._pool.size != n:
            self._pool = _core.ThreadPool(n)
        return self._pool

    def value(self, joint_state: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """(M,) values of (M, N, D) joint states with (M, N) real-human mask, as ``network.value``."""
        net = self.network
        if joint_state.dim() != 3 or joint_state.shape[-1] != net.input_dim:
            raise ValueError(
                f"{net.name}: expected joint state (M, N, {net.input_dim}), got {tuple(joint_state.shape)}"
            )
        if joint_state.shape[1] == 0:
            raise ValueError(f"{net.name}: N must be ≥ 1 (pad with one masked human)")
        if mask.shape != joint_state.shape[:2]:
            raise ValueError(
                f"{net.name}: mask {tuple(mask.shape)} does not match {tuple(joint_state.shape[:2])}"
            )
        joint = joint_state.detach().to(device="cpu", dtype=torch.float32).contiguous()
        m = mask.detach().to(device="cpu", dtype=torch.bool).contiguous()
        out = torch.empty(joint.shape[0], dtype=torch.float32)
        self._scorer().values(joint.numpy(), m.numpy(), out.numpy(), self._threads(), self.states_per_tile)
        return out
