"""The typed state of a value-based training run.

Its counters and schedule (:class:`TrainState`, saved in ``last.pt`` as the ``resume`` record) and
the curves' open window (:class:`CurveWindow`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

from socialnav.train.episodes import EpisodeStats
from socialnav.train.optim import load_optimizer_state, optimizer_state
from socialnav.train.value.run import ValueRun

#: The TrainState fields saved under the same names in the resume record.
RECORD_FIELDS = (
    "episode",
    "gradient_steps",
    "transitions",
    "credit",
    "next_target",
    "next_val",
    "next_ckpt",
    "next_log",
    "stream_positions",
    "best_val",
    "last_val",
)


@dataclass
class TrainState:
    """Counters and schedule of the RL phase.

    Everything a resumed run needs besides the networks, the optimizers and the generators.

    Attributes:
        episode: RL episodes counted so far (across resumptions).
        gradient_steps: gradient steps so far.
        transitions: transitions collected so far.
        credit: gradient steps owed at the replay ratio, not yet taken (fractional).
        next_target: the episode count at which the target network is next synchronised.
        next_val: the episode count of the next validation.
        next_ckpt: the episode count of the next ``last.pt``.
        next_log: the episode count of the next curves row.
        stream_positions: where each training world's episode stream stood at the last save.
        best_val: the best validation so far (with its ``episode``).
        last_val: the latest validation.
        wall_time_before: [s] spent by the calls before this one (0 on a fresh run).
    """

    episode: int
    gradient_steps: int
    transitions: int
    credit: float
    next_target: int
    next_val: int
    next_ckpt: int
    next_log: int
    stream_positions: Any
    best_val: dict[str, Any]
    last_val: dict[str, Any] | None
    wall_time_before: float = 0.0

    @classmethod
    def fresh(cls, run: ValueRun, first_validation: dict[str, Any]) -> TrainState:
        """The state after imitation: every counter at 0, the schedule at its first due points.

        Args:
            run: the run.
            first_validation: the validation after imitation (episode 0): the first best and last.

        Returns:
            The state.
        """
        rl = run.settings.rl
        return cls(
            episode=0,
            gradient_steps=0,
            transitions=0,
            credit=0.0,
            next_target=rl.target_update_every,
            next_val=rl.validate_every,
            next_ckpt=run.settings.checkpoint_every,
            next_log=run.settings.log_every,
            stream_positions=None,
            best_val=first_validation,
            last_val=first_validation,
        )

    @classmethod
    def from_record(cls, record: dict[str, Any]) -> TrainState:
        """The state a ``last.pt`` resume record holds.

        Args:
            record: the checkpoint's ``extra["resume"]``.

        Returns:
            The state, ``wall_time_before`` the saved run's wall time.
        """
        return cls(**{k: record[k] for k in RECORD_FIELDS}, wall_time_before=float(record["wall_time"]))

    def wall(self, run: ValueRun) -> float:
        """Wall time of the run so far [s], across resumptions."""
        return self.wall_time_before + time.perf_counter() - run.started


def resume_record(run: ValueRun, state: TrainState, stream_positions: Any) -> dict[str, Any]:
    """The ``resume`` record of ``last.pt``.

    The state, the target network, the optimizers, the generators and the training worlds' stream
    positions (not the replay memory).

    Args:
        run: the run.
        state: its state.
        stream_positions: the training worlds' ``stream_positions()``.

    Returns:
        Plain data and CPU tensors.
    """
    record = {
        **{k: getattr(state, k) for k in RECORD_FIELDS},
        "target_state_dict": {k: v.detach().cpu().clone() for k, v in run.target.state_dict().items()},
        "optimizer": optimizer_state(run.optimizer),
        "explore_rng": run.explore_gen.get_state(),
        "sample_rng": run.sample_gen.get_state(),
        "stream_positions": stream_positions,
        "wall_time": state.wall(run),
    }
    if run.predictor_optimizer is not None:
        record["predictor_optimizer"] = optimizer_state(run.predictor_optimizer)
    return record


def restore_from_record(run: ValueRun, record: dict[str, Any]) -> TrainState:
    """Puts the target network, the optimizers and the generators back as ``record`` saved them.

    Args:
        run: the run (its network and predictor are already loaded from ``last.pt``).
        record: the checkpoint's ``extra["resume"]``.

    Returns:
        The saved state.
    """
    run.target.load_state_dict(record["target_state_dict"])
    load_optimizer_state(run.optimizer, record["optimizer"])
    if run.predictor_optimizer is not None:
        load_optimizer_state(run.predictor_optimizer, record["predictor_optimizer"])
    run.explore_gen.set_state(record["explore_rng"])
    run.sample_gen.set_state(record["sample_rng"])
    return TrainState.from_record(record)


@dataclass
class CurveWindow:
    """What happened since the last curves row: training outcomes and mean losses.

    Attributes:
        stats: outcomes of the training episodes counted in the window.
        loss: sum of the TD losses of its gradient steps.
        predictor_loss: sum of the state predictor's losses of its gradient steps.
        steps: gradient steps in the window.
    """

    stats: EpisodeStats = field(default_factory=EpisodeStats)
    loss: float = 0.0
    predictor_loss: float = 0.0
    steps: int = 0

    def mean_loss(self) -> float:
        """Mean TD loss per gradient step (NaN without one)."""
        return self.loss / self.steps if self.steps else math.nan

    def mean_predictor_loss(self, has_predictor: bool) -> float:
        """Mean predictor loss per gradient step (NaN without a predictor or a step)."""
        return self.predictor_loss / self.steps if self.steps and has_predictor else math.nan

    def clear(self) -> None:
        """Empties the window (a row was written)."""
        self.stats, self.loss, self.predictor_loss, self.steps = EpisodeStats(), 0.0, 0.0, 0
