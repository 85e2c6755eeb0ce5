"""The value-based trainer: imitation from ORCA, then value-based RL, with checkpoints, curves and resumption.

Run directory (as every trainer's, train/run_directory.py)::

    config.yaml / config.json   the run's record (trainer, policy, preset, settings, derived seeds)
    il.pt                       the network after imitation learning
    best.pt                     best validation success so far (ties: fewer collisions, then faster)
    last.pt                     latest state: model + target network + optimizer + counters + RNG
                                states + best validation (no replay memory); re-running the same
                                command on the same directory resumes from it
    curves.csv                  one row per ``log_every`` RL episodes (and one per validation)
    tb/                         TensorBoard scalars, when ``torch.utils.tensorboard`` imports

Every checkpoint is a regular learned-policy checkpoint (``socialnav evaluate --checkpoint`` loads
any of them); its config holds ``value_policy`` so the evaluator scores actions as the trainer did.

The run reads top to bottom as its phases, each a function over the run (:class:`ValueRun`, built
once) and its typed state (:class:`TrainState`): setup (value/run.py), resume or imitation and the
first validation (value/state.py, value/imitation_phase.py), then the RL loop with its validations
and checkpoints (value/rl_phase.py). It is registered as the trainer ``value`` (train/registry.py).
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from socialnav.presets import Preset
from socialnav.train.value.imitation_phase import imitate_then_validate
from socialnav.train.value.rl_phase import OnValidation, build_learner, run_rl, save_last
from socialnav.train.value.run import setup_run
from socialnav.train.value.settings import TrainSettings
from socialnav.train.value.state import restore_from_record

__all__ = ["TrainResult", "train"]


@dataclass(frozen=True)
class TrainResult:
    """What a training call produced.

    Attributes:
        out_dir: the run directory.
        best_checkpoint: best.pt.
        last_checkpoint: last.pt.
        curves: curves.csv.
        episodes: RL episodes done in all (across resumptions).
        gradient_steps: gradient steps in all.
        best_val: the best validation (with its ``episode``).
        last_val: the latest validation.
        wall_time: [s] across resumptions.
        resumed: this call continued a run.
        finished: False when stopped early (``stop_after`` or ``on_validation``).
    """

    out_dir: Path
    best_checkpoint: Path
    last_checkpoint: Path
    curves: Path
    episodes: int
    gradient_steps: int
    best_val: dict[str, Any]
    last_val: dict[str, Any] | None
    wall_time: float
    resumed: bool
    finished: bool


def train(
    policy_name: str,
    preset: Preset | str,
    out_dir: str | Path,
    settings: TrainSettings | None = None,
    *,
    progress: bool = True,
    stop_after: int | None = None,
    log=None,
    on_validation: OnValidation | None = None,
) -> TrainResult:
    """Imitation learning from ORCA, then value-based RL; resumes from ``out_dir/last.pt`` if present.

    Args:
        policy_name: a value-based learned policy: cadrl, lstm_rl (ga3c_cadrl), sarl, om_sarl, rgl, mp_rgl.
        preset: a Preset or a preset name/path (world semantics, robot, training scenario mix).
        out_dir: run directory (created; resumed when it holds last.pt).
        settings: training settings (default: TrainSettings()); ``settings.policy`` is replaced by
            ``policy_name``.
        progress: tqdm progress bars on stderr.
        stop_after: stop after this many RL episodes in THIS call without a final checkpoint (as if
            the process were killed; for tests of resumption).
        log: callable taking a line of text (default: print to stderr).
        on_validation: callable ``(episode, val_metrics, wall_time) -> bool`` called after every
            validation (episode 0 is the one after imitation); True stops training there (last.pt is
            written first, so the run can be resumed).

    Returns:
        The run's files, counters and validations.

    Raises:
        TrainingDiverged: the loss became NaN/inf (last.pt and best.pt keep the last good state).
        ConfigError: resuming with settings that differ from the run's (the keys are named).
        DirectoryLockedError: another training is writing to ``out_dir``.

    Nothing is written to ``out_dir`` before the settings, the worlds and a resumed checkpoint have
    been checked, so a refused run leaves no half-written directory behind.
    """
    with contextlib.ExitStack() as stack:  # closes the worlds and releases the run directory's lock
        run = setup_run(policy_name, preset, out_dir, settings, stack, progress=progress, log=log)
        # a run interrupted during imitation has no last.pt yet, but continues from its files
        continued = run.resumed is not None or any(
            (run.out / name).exists() for name in ("il.pt", "il_state.pt", "il_demos.npz"))
        if run.resumed is not None:
            state = restore_from_record(run, run.resumed)
            stopped = False
        else:
            state = imitate_then_validate(run)
            stopped = bool(on_validation and on_validation(0, state.best_val, state.wall(run)))
            run.save(run.best_path, {"episode": 0, "val": state.best_val})
            run.target.load_state_dict(run.net.state_dict())
        learner = build_learner(run, state, stack)
        if run.resumed is None:
            save_last(run, state, learner)
        if not stopped:
            stopped = run_rl(run, state, learner, stop_after=stop_after, on_validation=on_validation)
        if not stopped and state.episode >= run.settings.rl.episodes and not run.last_path.exists():
            save_last(run, state, learner)
        return TrainResult(
            run.out,
            run.best_path,
            run.last_path,
            run.curves_path,
            int(state.episode),
            int(state.gradient_steps),
            dict(state.best_val),
            state.last_val,
            state.wall(run),
            continued,
            not stopped,
        )
