"""The validation and reporting phase of a PPO update.

The deterministic policy on the validation episodes (best.pt on a better one) and the curves row of
the window since the last one.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import torch

from socialnav.train.curves import validation_columns, window_columns
from socialnav.train.episodes import GreedyActor, better, validate
from socialnav.train.ppo.run import PPORun
from socialnav.train.ppo.state import PPOState

if TYPE_CHECKING:  # the rollout is made by the trainer that imports this module
    from socialnav.train.ppo.algorithm import Rollout


def validate_if_due(run: PPORun, state: PPOState, actor) -> dict[str, Any] | None:
    """Validation every ``validate_every`` updates and after the last one.

    Args:
        run: the run.
        state: its state (``last_val`` and ``best_val`` advance).
        actor: the run's RecurrentActorPolicy (reset first: validation episodes start afresh).

    Returns:
        The validation (with its ``update``), or None when none was due.
    """
    u = state.update
    if not (u % run.settings.validate_every == 0 or u == run.n_updates):
        return None
    actor.reset()
    run.net.eval()
    val = validate(GreedyActor(actor), run.val_world, False, run.preset.world.reward.success_reward)
    val["update"] = u
    state.last_val = val
    if better(val, state.best_val):
        state.best_val = val
        run.save(run.best_path, {"update": u, "val": val})
    assert state.best_val is not None
    run.say(
        f"update {u}: validation success {val['success']:.3f} collision {val['collision']:.3f} "
        f"timeout {val['timeout']:.3f} (best {state.best_val['success']:.3f})"
    )
    return val


def write_row_if_due(
    run: PPORun, state: PPOState, rollout: Rollout, val: dict[str, Any] | None, lr: float, bar
) -> None:
    """A curves row every ``log_every`` updates, after a validation and after the last update.

    Args:
        run: the run.
        state: its state (its window is written and cleared).
        rollout: the last update's rollout (explained variance).
        val: the validation just made, if any.
        lr: the last update's learning rate.
        bar: the progress bar (its postfix shows the row).
    """
    u = state.update
    if not (u % run.settings.log_every == 0 or val is not None or u == run.n_updates):
        return
    rates = state.stats.rates()
    n = state.losses.pop("n")
    busy = max(state.collect_time + state.update_time, 1e-9)
    row = {
        "phase": "il" if u <= run.settings.imitation_updates else "ppo",  # il: as the value trainer's
        "update": u,
        "env_steps": state.env_steps,
        "episodes": state.episodes,
        **window_columns(rates, state.stats.total),
        "train_return": state.returns_sum / state.returns_n if state.returns_n else math.nan,
        **{k: v / n for k, v in state.losses.items()},
        "explained_variance": explained_variance(rollout.values.flatten(), rollout.returns.flatten()),
        "std": float(run.net.log_std.detach().exp().mean()),
        "lr": lr,
        "env_steps_per_s": (run.n_envs * run.settings.rollout_steps * state.updates_this_call) / busy,
        "wall_time": state.wall(run),
    }
    row.update(validation_columns(val))
    run.curves.write(row)
    bar.set_postfix(succ=f"{rates['success']:.2f}", kl=f"{row['approx_kl']:.3g}", refresh=False)
    state.clear_window()


def explained_variance(values: torch.Tensor, returns: torch.Tensor) -> float:
    """1 − Var(R − V) / Var(R) (NaN when the returns do not vary)."""
    var = float(returns.var(unbiased=False))
    return math.nan if var == 0 else 1.0 - float((returns - values).var(unbiased=False)) / var
