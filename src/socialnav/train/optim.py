"""The optimizers of every trainer.

Adam (fused where torch offers it), its fast step and saved state, the compiled loss, and the error
a diverged loss raises.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

import torch


class TrainingDiverged(RuntimeError):
    """The loss became NaN or infinite; training stopped and the last good checkpoint was kept."""


def make_optimizer(params, lr: float, device: torch.device) -> torch.optim.Optimizer:
    """Adam over ``params``, fused where torch offers it (else ``foreach``).

    Args:
        params: the parameters.
        lr: learning rate.
        device: where they live.

    Returns:
        The optimizer.
    """
    params = list(params)
    try:  # fused Adam: one kernel for all parameters (2-3x faster steps for these small networks)
        return torch.optim.Adam(params, lr=lr, fused=True)
    except (RuntimeError, TypeError, ValueError):
        return torch.optim.Adam(params, lr=lr, foreach=True)


def compile_loss(loss: Callable[[torch.Tensor], torch.Tensor], device: torch.device):
    """``torch.compile`` of a minibatch loss of index tensors (training setting ``compile``).

    Static shapes (one graph per minibatch size) and, on CPU, Inductor's C++ wrapper, which calls
    the graph's kernels from C++ instead of Python: ≈ 30 % less time per call on the 2-core VM, at no
    extra compile time (docs/training.md, "Compiled training").

    Args:
        loss: ``loss(indices)`` of a minibatch.
        device: where the loss runs.

    Returns:
        The compiled loss.
    """
    options = {"cpp_wrapper": True} if device.type == "cpu" else {}
    use_inductor_cache_of_these_kernels()
    return torch.compile(loss, dynamic=False, options=options)


def use_inductor_cache_of_these_kernels() -> None:
    """Gives Inductor an on-disk cache of its own per CPU capability, unless the user chose one.

    Inductor keys its cached kernels by the graph, not by the vector ISA ATen runs with: kernels compiled
    under AVX-512 were reused with ``ATEN_CPU_CAPABILITY=avx2`` on the same machine and failed (an index
    out of bounds inside a generated kernel). Inductor writes its default directory into
    ``TORCHINDUCTOR_CACHE_DIR`` the first time it compiles, so that value counts as unset; any other is
    the user's and is left alone. Called before every compilation (``compile_loss``, the fused step).
    """
    from torch._inductor.runtime.cache_dir_utils import default_cache_dir

    current = os.environ.get("TORCHINDUCTOR_CACHE_DIR")
    inductors_default = default_cache_dir()
    if current and os.path.abspath(current) != os.path.abspath(inductors_default):
        return
    capability = torch.backends.cpu.get_cpu_capability().lower()
    os.environ["TORCHINDUCTOR_CACHE_DIR"] = f"{inductors_default}_{capability}"


class AdamSteps:
    """``zero_grad()`` and ``step()`` of a fused Adam without the optimizer's per-call Python.

    ``torch.optim.Adam(fused=True).step()`` spends most of its time, for networks of a few small
    tensors, in Python around its kernels (bookkeeping per parameter, grouping by device and dtype,
    hooks) and in one step-counter add per parameter tensor. This increments the counters and calls
    the same fused kernel (``_fused_adam_``) with the same arguments on the optimizer's own state, so
    the parameters and the saved optimizer state are bit-identical to ``optimizer.step()``
    (``tests/train/test_adam_steps.py``); the counters are kept as views of one tensor, so one add
    replaces the per-parameter adds. Measured on the 2-core VM, SARL's 22 tensors: 96–105 µs per step
    against 287–304 µs. Anything else — a first step (which creates the state), a parameter without a
    gradient, several parameter groups, amsgrad, weight decay, maximize, a non-fused optimizer — goes
    through ``optimizer.step()``. ``zero_grad()`` is ``zero_grad(set_to_none=True)``.
    """

    def __init__(self, optimizer: torch.optim.Optimizer) -> None:
        """Wraps ``optimizer`` (its state is used, never copied).

        Args:
            optimizer: the optimizer whose steps are taken.
        """
        self.optimizer = optimizer
        groups = optimizer.param_groups
        g = groups[0]
        self.params: list[torch.Tensor] = list(g["params"])
        self.fast = (
            isinstance(optimizer, torch.optim.Adam)
            and len(groups) == 1
            and bool(g.get("fused"))
            and not g.get("amsgrad")
            and not g.get("maximize")
            and not g.get("capturable")
            and not g.get("differentiable")
            and not g.get("decoupled_weight_decay", False)
            and g.get("weight_decay", 0) == 0
            and not isinstance(g.get("lr"), torch.Tensor)
            and not optimizer._optimizer_step_pre_hooks
            and not optimizer._optimizer_step_post_hooks
            and hasattr(torch, "_fused_adam_")
        )

        # Cached per-parameter state; the step counters become 0-d views of one tensor, so that one
        # add per step replaces one per parameter (the same values). Rebuilt whenever the optimizer's
        # state object is replaced (load_state_dict, e.g. on resume).
        self._state: Any = None
        self._steps_buffer = torch.zeros(0)
        self._steps: list[torch.Tensor] = []
        self._exp_avgs: list[torch.Tensor] = []
        self._exp_avg_sqs: list[torch.Tensor] = []

    def zero_grad(self) -> None:
        """Drops the gradients (``zero_grad(set_to_none=True)``)."""
        for p in self.params:
            p.grad = None

    def _cache(self, state: Any) -> None:
        per_param = [state[p] for p in self.params]
        self._steps_buffer = shared_step_counters(per_param)
        self._steps = [s["step"] for s in per_param]
        self._exp_avgs = [s["exp_avg"] for s in per_param]
        self._exp_avg_sqs = [s["exp_avg_sq"] for s in per_param]
        self._state = state

    def step(self) -> None:
        """One Adam step, as ``optimizer.step()``."""
        state = self.optimizer.state
        grads = [p.grad for p in self.params]
        if not self.fast or len(state) < len(self.params) or any(g is None for g in grads):
            self.optimizer.step()  # also the first step, which creates the state
            return
        if state is not self._state:
            self._cache(state)
        group = self.optimizer.param_groups[0]
        beta1, beta2 = group["betas"]
        with torch.no_grad():
            self._steps_buffer.add_(1)
            torch._fused_adam_(
                self.params,
                grads,
                self._exp_avgs,
                self._exp_avg_sqs,
                [],
                self._steps,
                amsgrad=False,
                lr=group["lr"],
                beta1=beta1,
                beta2=beta2,
                weight_decay=group["weight_decay"],
                eps=group["eps"],
                maximize=False,
                grad_scale=None,
                found_inf=None,
            )


def shared_step_counters(per_param: list[dict[str, Any]]) -> torch.Tensor:
    """Makes every parameter's Adam ``step`` counter a view of one stacked tensor.

    Each counter (a 0-d tensor) is replaced by a 0-d view of one tensor with the same values: one
    add advances every counter, and the optimizer's state (saved, loaded, stepped by
    ``optimizer.step()``) holds the views where it held the counters.

    Args:
        per_param: the optimizer's state of each parameter.

    Returns:
        The stacked counters.
    """
    steps = torch.stack([s["step"].detach() for s in per_param])
    for i, s in enumerate(per_param):
        s["step"] = steps[i]
    return steps


def optimizer_state(opt: torch.optim.Optimizer) -> dict[str, Any]:
    """An optimizer's state dict with string keys (what a checkpoint's ``extra`` holds).

    Args:
        opt: the optimizer.

    Returns:
        ``{"state": {"0": ...}, "param_groups": [...]}``.
    """
    sd = opt.state_dict()
    return {"state": {str(k): v for k, v in sd["state"].items()}, "param_groups": sd["param_groups"]}


def load_optimizer_state(opt: torch.optim.Optimizer, data: dict[str, Any]) -> None:
    """Loads what :func:`optimizer_state` saved.

    Args:
        opt: the optimizer.
        data: the saved state.
    """
    groups = []
    for g in data["param_groups"]:
        g = dict(g)
        if isinstance(g.get("betas"), list):
            g["betas"] = tuple(g["betas"])
        groups.append(g)
    opt.load_state_dict({"state": {int(k): v for k, v in data["state"].items()}, "param_groups": groups})
