"""The typed state of a PPO training run and its checkpoint.

:class:`PPOState` holds the counters, the GRU states of the episodes in flight and the curves' open
window; ``last.pt`` saves it with the network, the optimizer, the generators and the worlds, so that
a resumed run goes on exactly where it stopped (bit-identical on CPU).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch

from socialnav.train.episodes import EpisodeStats
from socialnav.train.optim import optimizer_state
from socialnav.train.ppo.run import PPORun
from socialnav.train.ppo.worlds import world_snapshot

#: PPOState fields saved under the same names in the resume record.
COUNTERS = ("update", "env_steps", "episodes", "best_val", "last_val")


@dataclass
class PPOState:
    """Counters, the episodes in flight and the curves' window of a PPO run.

    Attributes:
        update: updates done (across resumptions).
        env_steps: environment steps collected.
        episodes: training episodes ended.
        best_val: the best validation so far (with its ``update``), or None.
        last_val: the latest validation, or None.
        h: (n_envs, ...) the GRU state of each environment's episode in flight.
        start: (n_envs,) bool, the environments whose next step starts an episode.
        obs: the observation the next step acts on (not saved: the restored worlds give it again).
        stats: outcomes of the training episodes since the last curves row.
        returns_sum: sum of the undiscounted returns of those episodes.
        returns_n: their number.
        losses: sums of the updates' mean losses since the last row (``n``: updates summed).
        episode_return: (n_envs,) undiscounted return of each episode in flight.
        wall_time_before: [s] spent by the calls before this one.
        collect_time: [s] in this call, stepping the worlds and acting.
        update_time: [s] in this call, GAE and the gradient steps.
        updates_this_call: updates done in this call.
    """

    update: int
    env_steps: int
    episodes: int
    best_val: dict[str, Any] | None
    last_val: dict[str, Any] | None
    h: torch.Tensor
    start: torch.Tensor
    obs: Any
    stats: EpisodeStats = field(default_factory=EpisodeStats)
    returns_sum: float = 0.0
    returns_n: int = 0
    losses: dict[str, float] = field(default_factory=dict)
    episode_return: np.ndarray = field(default_factory=lambda: np.zeros(0))
    wall_time_before: float = 0.0
    collect_time: float = 0.0
    update_time: float = 0.0
    updates_this_call: int = 0

    def wall(self, run: PPORun) -> float:
        """Wall time of the run so far [s], across resumptions."""
        return self.wall_time_before + time.perf_counter() - run.started

    def clear_window(self) -> None:
        """Empties the curves' window (a row was written)."""
        self.stats, self.returns_sum, self.returns_n, self.losses = EpisodeStats(), 0.0, 0, {}


def initial_state(run: PPORun) -> PPOState:
    """The state a run starts or resumes with.

    A fresh run starts every environment's episode with the network's initial GRU state; with
    ``normalize_obs`` the first observation's statistics are taken in for the first rollout. A
    resumed run gets its counters, GRU states and curves' window back from ``last.pt``.

    Args:
        run: the run (its worlds already restored or reset).

    Returns:
        The state.
    """
    from socialnav.policies.learned.ppo_inputs import network_inputs

    n_envs, device, obs = run.n_envs, run.device, run.world.observe()
    saved = run.resumed
    if saved is None:
        state = PPOState(
            update=0,
            env_steps=0,
            episodes=0,
            best_val=None,
            last_val=None,
            h=run.net.initial_state(n_envs, device),
            start=torch.ones(n_envs, dtype=torch.bool, device=device),
            obs=obs,
            episode_return=np.zeros(n_envs),
        )
        if run.settings.normalize_obs:
            run.net.update_obs_stats(
                *network_inputs(run.net, obs, run.preset.world.dt, device, run.obstacle_encoding)
            )
        return state
    window = saved["window"]
    return PPOState(
        **{k: saved[k] for k in COUNTERS},
        h=saved["h"].to(device),
        start=saved["start"].to(device),
        obs=obs,
        stats=EpisodeStats(**window["stats"]),
        returns_sum=float(window["returns_sum"]),
        returns_n=int(window["returns_n"]),
        losses=dict(window["losses"]),
        episode_return=window["episode_return"].numpy().copy(),
        wall_time_before=float(saved["wall_time"]),
    )


def save_last(run: PPORun, state: PPOState) -> None:
    """Writes ``last.pt``: the network and everything a resumed run needs.

    The counters, optimizer, generators, the worlds' episodes in flight with their GRU states, and
    the curves' window (so that a resumed run writes the rows an uninterrupted one would).

    Args:
        run: the run.
        state: its state.
    """
    resume = {
        **{k: getattr(state, k) for k in COUNTERS},
        "wall_time": state.wall(run),
        "optimizer": optimizer_state(run.optimizer),
        "action_rng": run.action_gen.get_state(),
        "minibatch_rng": run.minibatch_gen.get_state(),
        "worlds": world_snapshot(run.world),
        "h": state.h.detach().cpu().clone(),
        "start": state.start.cpu().clone(),
        "window": {
            "stats": dataclasses.asdict(state.stats),
            "returns_sum": state.returns_sum,
            "returns_n": state.returns_n,
            "losses": dict(state.losses),
            "episode_return": torch.from_numpy(state.episode_return.copy()),
        },
    }
    run.save(run.last_path, {"phase": "ppo", "resume": resume})
