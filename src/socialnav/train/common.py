"""Pieces shared by the training phases.

Devices, optimizers and their saved state, progress bars, the validation order, and the check that
a run directory holds this run.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch

from socialnav._progress import progress_bar as shared_progress_bar
from socialnav.config import ConfigError
from socialnav.train.config import resume_diff


class RunFiles:
    """The files of a training run directory, shared by the run records of both trainers.

    A mixin: the record (a frozen dataclass) provides ``out``, the run directory.
    """

    out: Path

    @property
    def last_path(self) -> Path:
        """last.pt: the latest training state (resumption)."""
        return self.out / "last.pt"

    @property
    def best_path(self) -> Path:
        """best.pt: the best validation so far."""
        return self.out / "best.pt"

    @property
    def curves_path(self) -> Path:
        """curves.csv: one row per logged episode or update."""
        return self.out / "curves.csv"


def resolve_device(name: str) -> torch.device:
    """The torch device a training setting ``device`` names.

    Args:
        name: ``auto`` (CUDA when available, else CPU), ``cpu``, ``cuda`` or any torch device name.

    Returns:
        The device.

    Raises:
        RuntimeError: ``cuda`` was asked for and CUDA is not available.
    """
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name == "cuda" and not torch.cuda.is_available():
        raise RuntimeError(
            "device 'cuda' requested but torch.cuda.is_available() is False (use --device cpu)"
        )
    return torch.device(name)


def check_config_device(config: str | None, device: str, given: str | None) -> None:
    """Names the config file where a ``device: cuda`` it sets cannot be had (not the command line's).

    Raises:
        ConfigError: The file asks for CUDA and this machine has none.
    """
    if given is None and config is not None and device == "cuda" and not torch.cuda.is_available():
        raise ConfigError(f"--config {config}: device: cuda, and torch.cuda.is_available() is False here "
                          "(give --device cpu, or device: auto in the file)")


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
    return torch.compile(loss, dynamic=False, options=options)


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
    ``optimizer.step()``) holds the views as before.

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


def progress_bar(total: int, initial: int, desc: str, enabled: bool):
    """A tqdm bar on stderr (:mod:`socialnav._progress`).

    Args:
        total: the count at completion.
        initial: the count already done (a resumed run).
        desc: its label.
        enabled: False: a disabled bar (same calls, no output).

    Returns:
        The bar.
    """
    return shared_progress_bar(total, initial, desc=desc, enabled=enabled)


def better(a: dict[str, Any], b: dict[str, Any] | None) -> bool:
    """Validation a better than b: higher success, then fewer collisions, then faster.

    Args:
        a: a validation.
        b: the best so far, or None.

    Returns:
        Whether a is better.
    """
    if b is None:
        return True

    def key(m: dict[str, Any]) -> tuple:
        nt = m.get("nav_time")
        return (m["success"], -m["collision"], -(nt if nt is not None and not math.isnan(nt) else 1e9))

    return key(a) > key(b)


def recorded_config(out: Path) -> dict[str, Any] | None:
    """The settings a run recorded in ``<out>/config.json`` when it started, or None where there is none.

    A run killed before its first ``last.pt`` leaves only this record (and imitation's files): another
    run started into the directory must be checked against it, or it would overwrite that run.

    Raises:
        ConfigError: The record is not a JSON object.
    """
    path = out / "config.json"
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError) as err:
        raise ConfigError(f"{path}: the run's record cannot be read ({err}); move the directory away or "
                          "use another --out") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: the run's record is not a JSON object; use another --out")
    return data


def check_same_run(saved: dict[str, Any], config: dict[str, Any], out: Path) -> None:
    """Refuses to resume a run directory written with other settings (naming keys and values).

    Args:
        saved: the run directory's record.
        config: this call's record.
        out: the run directory.

    Raises:
        ConfigError: the settings differ.
    """
    refuse_other_settings(saved, config, resume_diff(saved, config), out)


def refuse_other_settings(saved: dict[str, Any], config: dict[str, Any], diff: list[str], out: Path) -> None:
    """Refuses a resume where ``diff`` (dotted keys) is not empty, naming each key's two values.

    The one message of both trainers, which decide differently which keys may change.

    Raises:
        ConfigError: ``diff`` names keys.
    """
    if diff:
        if "policy" in diff:  # another policy's run (maybe of the other trainer): said first, not 6th of 30
            diff = ["policy", *(k for k in diff if k != "policy")]
        changes = "; ".join(f"{k}: {dotted(saved, k)!r} -> {dotted(config, k)!r}" for k in diff[:6])
        raise ConfigError(
            f"{out} holds a run with other settings ({changes}{'; ...' if len(diff) > 6 else ''}); "
            f"use another --out or the run's own settings (config.yaml)"
        )


def load_resume_checkpoint(last_path: Path, policy: str, out: Path, **kwargs: Any) -> Any:
    """A run directory's ``last.pt``, refused naming the directory when it holds another policy's run.

    Args:
        last_path: The run's ``last.pt``.
        policy: The policy being trained.
        out: The run directory.
        **kwargs: Passed to :func:`~socialnav.policies.learned.load_checkpoint`.

    Returns:
        The checkpoint.

    Raises:
        ConfigError: The directory holds a run of another policy.
        CheckpointError: The file is damaged.
    """
    from socialnav.policies.learned import load_checkpoint
    from socialnav.policies.learned.checkpoint import CheckpointError

    try:
        return load_checkpoint(last_path, policy, **kwargs)
    except CheckpointError as err:
        if " holds policy " not in str(err):
            raise
        raise ConfigError(f"{out} holds a training run of another policy ({err}); train {policy!r} into "
                          "another --out, or move that run away") from None


def dotted(data: Any, key: str) -> Any:
    """The value at a dotted key (``train.seed``) of nested dicts, or None."""
    for part in key.split("."):
        data = data.get(part) if isinstance(data, dict) else None
    return data


def reward_config(world: Any) -> dict[str, float]:
    """The reward constants a checkpoint records for ``world``.

    The evaluator compares them (policies/learned_entries.py).

    Args:
        world: a preset's WorldSettings.

    Returns:
        Success reward, collision penalty, discomfort distance and factor, time step.
    """
    return {
        "success_reward": world.reward.success_reward,
        "collision_penalty": world.reward.collision_penalty,
        "discomfort_dist": world.reward.discomfort_dist,
        "discomfort_penalty_factor": world.reward.discomfort_penalty_factor,
        "time_step": world.dt,
    }
