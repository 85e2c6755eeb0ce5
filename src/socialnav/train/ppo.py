"""`socialnav train --policy crowdnav_pp` (or `ppo_mlp`): PPO with a recurrent actor-critic.

Reads top to bottom like a CleanRL script (Huang et al., "CleanRL", JMLR 2022): setup (settings,
seeds, the network and the worlds: train/ppo_run.py), resume or start (train/ppo_state.py), then per
update a rollout collected from every environment in lockstep (one native call per world of the
training mix per step) and GAE (train/ppo_rollout.py), epochs of clipped-objective minibatch steps
over whole environment sequences (train/ppo_update.py), validation and curves
(train/ppo_validation.py) and the checkpoint. The network is in policies/learned/attn_graph.py, the
objective in train/ppo_objective.py, the settings in train/ppo_config.py; docs/ppo.md explains the
choices.

Run directory layout (as the value-based trainer's)::

    config.yaml / config.json   resolved settings (policy, preset, PPO settings, derived seeds)
    best.pt                     best validation success so far (ties: fewer collisions, then faster)
    last.pt                     network + optimizer + generators + counters + the worlds' state and
                                the GRU states of the episodes in flight: re-running the same command
                                resumes exactly where it stopped (bit-identical on CPU)
    curves.csv                  one row per ``log_every`` updates
"""

from __future__ import annotations

import contextlib
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from socialnav.config import ConfigError
from socialnav.presets import Preset, load_preset
from socialnav.train.common import check_config_device, progress_bar
from socialnav.train.ppo_config import PPOSettings
from socialnav.train.ppo_rollout import collect_rollout
from socialnav.train.ppo_run import PPO_CURVE_COLUMNS, PPO_STREAM_OFFSET, setup_ppo_run
from socialnav.train.ppo_state import initial_state, save_last
from socialnav.train.ppo_update import ppo_update, set_learning_rate
from socialnav.train.ppo_validation import validate_if_due, write_row_if_due

__all__ = ["PPOResult", "train_ppo", "train_ppo_from_args", "PPO_CURVE_COLUMNS", "PPO_STREAM_OFFSET"]


@dataclass(frozen=True)
class PPOResult:
    """What a PPO training call produced.

    Attributes:
        out_dir: the run directory.
        best_checkpoint: best.pt.
        last_checkpoint: last.pt.
        curves: curves.csv.
        updates: updates done in all (across resumptions).
        env_steps: environment steps in all.
        episodes: training episodes ended in all.
        best_val: the best validation (with its ``update``), or None.
        wall_time: [s] across resumptions.
        resumed: this call continued a run.
        finished: False when stopped early by ``stop_after``.
        collect_time: [s] in this call: stepping the worlds and acting.
        update_time: [s] in this call: GAE and the gradient steps.
    """

    out_dir: Path
    best_checkpoint: Path
    last_checkpoint: Path
    curves: Path
    updates: int
    env_steps: int
    episodes: int
    best_val: dict[str, Any] | None
    wall_time: float
    resumed: bool
    finished: bool
    collect_time: float
    update_time: float


def train_ppo(
    preset: Preset | str,
    out_dir: str | Path,
    settings: PPOSettings | None = None,
    *,
    progress: bool = True,
    stop_after: int | None = None,
    log=None,
) -> PPOResult:
    """PPO under ``preset``'s training mix; resumes from ``out_dir/last.pt`` if present.

    Args:
        preset: a Preset or a preset name/path (world semantics, robot, training scenario mix).
        out_dir: run directory (created; resumed when it holds last.pt).
        settings: PPO settings (default: ``PPOSettings()``, crowdnav_pp).
        progress: tqdm progress bar on stderr.
        stop_after: stop after this many updates in THIS call, as if killed after the checkpoint of
            that update (for tests of resumption; the checkpoint is written there).
        log: callable taking a line of text (default: print to stderr).

    Returns:
        The run's files, counters and timings.

    Raises:
        ConfigError: resuming with settings that differ from the run's (the keys are named).
        TrainingDiverged: the loss became NaN/inf (last.pt keeps the last good state).
    """
    from socialnav.policies.learned.ppo_policy import RecurrentActorPolicy

    with contextlib.ExitStack() as stack:  # closes the worlds and releases the run directory's lock
        run = setup_ppo_run(preset, out_dir, settings or PPOSettings(), stack, progress=progress, log=log)
        w = run.preset.world
        actor = RecurrentActorPolicy(
            run.settings.policy, run.net, kinematics=w.kinematics, rotation_limit=w.rotation_limit, dt=w.dt,
            device=run.device, obstacle_encoding=run.obstacle_encoding,
        )
        state = initial_state(run)
        if run.resumed is not None and state.update > run.n_updates:
            run.say(f"note: {run.out} already holds {state.update} updates ({state.env_steps} env steps), "
                    f"more than this budget's {run.n_updates}: nothing to train (the run is not shortened)")
        bar = progress_bar(run.n_updates, state.update, f"{run.settings.policy} PPO", progress)
        stack.callback(bar.close)
        finished = True
        while state.update < run.n_updates:
            lr = set_learning_rate(run, state)
            rollout = collect_rollout(run, state)
            ppo_update(run, state, rollout)
            bar.update(1)
            val = validate_if_due(run, state, actor)
            write_row_if_due(run, state, rollout, val, lr, bar)
            u = state.update
            stopping = stop_after is not None and state.updates_this_call >= stop_after and u < run.n_updates
            if u % run.settings.checkpoint_every == 0 or u == run.n_updates or stopping:
                save_last(run, state)
            if stopping:
                finished = False
                break
        if finished and not run.last_path.exists():
            save_last(run, state)  # a run with no update at all (total_env_steps 0)
        return PPOResult(
            run.out,
            run.best_path,
            run.last_path,
            run.out / "curves.csv",
            int(state.update),
            int(state.env_steps),
            int(state.episodes),
            state.best_val,
            state.wall(run),
            run.resumed is not None,
            finished,
            state.collect_time,
            state.update_time,
        )


def train_ppo_from_args(args) -> int:
    """Entry point of ``socialnav train --policy crowdnav_pp`` (or ``ppo_mlp``; see train/cli.py).

    Args:
        args: the parsed command line.

    Returns:
        The exit status (0); the summary is printed as one JSON line.

    Raises:
        ConfigError: a value-based option was given.
    """
    from socialnav.train.ppo_config import load_ppo_settings

    refused = [
        flag
        for flag, key in (
            ("--information", "information"),
            ("--rl-episodes", "rl_episodes"),
            ("--compile", "compile"),
        )
        if getattr(args, key, None) is not None
    ]
    if refused:
        raise ConfigError(
            f"{', '.join(refused)}: not a setting of PPO training (policy {args.policy}); "
            "see docs/ppo.md for its settings"
        )
    settings = load_ppo_settings(
        getattr(args, "config", None) or "ppo",  # the shipped default schedule
        seed=args.seed,
        device=args.device,
        n_envs=getattr(args, "collection_batch", None),
        total_env_steps=getattr(args, "env_steps", None),
        policy=args.policy,
    )
    check_config_device(getattr(args, "config", None), settings.device, getattr(args, "device", None))
    preset = load_preset(args.preset)
    out = Path(args.out or f"runs/train/{preset.name}-{args.policy}-s{settings.seed}")
    result = train_ppo(preset, out, settings, progress=not getattr(args, "no_progress", False))
    best = result.best_val or {}
    print(
        json.dumps(
            {
                "out": str(result.out_dir),
                "best_checkpoint": str(result.best_checkpoint),
                "updates": result.updates,
                "env_steps": result.env_steps,
                "episodes": result.episodes,
                "best_val": {
                    k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in best.items()
                },
                "wall_time_s": round(result.wall_time, 1),
                "resumed": result.resumed,
            }
        )
    )
    return 0
