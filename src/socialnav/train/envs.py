"""The training scenario mix as one batch: one World per scenario, stepped together.

``MultiWorld`` concatenates the observations of its worlds (all share N human slots) so that the
policy scores every slot of every scenario in one call, and splits the actions back.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from socialnav.presets import Preset
from socialnav.scenarios import make_scenario
from socialnav.sim.observation import Observation
from socialnav.sim.world import World


def training_n_humans(preset: Preset, policy: str, cadrl_one_human: bool = True) -> int:
    """Humans per training episode: the preset's, or 1 for a policy whose record asks for it (CADRL,
    trained with one human, as its authors did) while ``cadrl_one_human`` is on."""
    from socialnav.policies.learned_catalog import get_learned_spec, learned_policy_names

    if cadrl_one_human and policy in learned_policy_names() and get_learned_spec(policy).one_human_training:
        return 1
    return int(preset.training.n_humans)


def split_counts(total: int, parts: int) -> list[int]:
    """``total`` split as evenly as possible over ``parts`` (the first ones get the remainder)."""
    base, rem = divmod(int(total), int(parts))
    return [base + (1 if i < rem else 0) for i in range(parts)]


@dataclass
class MultiStep:
    """What a MultiWorld step returns (arrays over all slots)."""

    reward: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    final_robot: np.ndarray  # (B, 9): state after the step (pre-reset for finished slots)
    final_humans: np.ndarray  # (B, N, 5)
    final_mask: np.ndarray  # (B, N)
    final_time: np.ndarray  # (B,)


class MultiWorld:
    """Worlds of the scenario mix stepped in lockstep.

    Args:
        preset: world semantics, robot and training scenario mix.
        n_humans: humans per episode.
        batch_size: total slots, split evenly over the scenarios (at least one each).
        split: "train" (endless stream from ``start``) or "val" (``count`` episodes in all).
        start: first episode index of every scenario's stream.
        count: total episodes (split over the scenarios), or None for endless streams.
        threads: native worker threads per world (0: the preset's setting).
    """

    def __init__(
        self,
        preset: Preset,
        n_humans: int,
        batch_size: int,
        split: str,
        start: int = 0,
        count: int | None = None,
        threads: int = 0,
    ) -> None:
        names = list(preset.training.scenarios)
        if not names:
            raise ValueError("the preset's training scenario mix is empty")
        settings = dataclasses.replace(
            preset.world, visibility=preset.training.visibility, continue_after_success=False
        )
        if threads:
            settings = dataclasses.replace(settings, threads=threads)
        self.names = names
        self.settings = settings
        self.start = int(start)
        counts = split_counts(count, len(names)) if count is not None else [None] * len(names)
        sizes = [max(1, b) for b in split_counts(batch_size, len(names))]
        self.worlds: list[World] = []
        for name, size, cnt in zip(names, sizes, counts, strict=True):
            if cnt == 0:
                continue
            scenario = make_scenario(
                name, n_humans=n_humans, robot_v_pref=preset.robot.v_pref, robot_radius=preset.robot.radius
            )
            b = size if cnt is None else max(1, min(size, cnt))
            self.worlds.append(
                World(settings, scenario, b, split=split, start=start, count=cnt, record=False)
            )
        self.sizes = [w.batch_size for w in self.worlds]
        self.offsets = np.cumsum([0, *self.sizes])
        self.batch_size = int(self.offsets[-1])
        self.dt = settings.dt

    def close(self) -> None:
        """Stops every world's native threads now (see World.close)."""
        for w in self.worlds:
            w.close()

    def reset(self, starts: list[int] | None = None) -> None:
        """Restarts every stream at ``start`` (or at ``starts[i]``) and fills every slot."""
        for i, w in enumerate(self.worlds):
            w.restart(self.start if starts is None else int(starts[i]))

    def stream_positions(self) -> list[int]:
        """Next episode index each world's stream will hand out (for resumption)."""
        return [int(w.stream.next_index) for w in self.worlds]

    @property
    def busy(self) -> bool:
        return any(w.busy for w in self.worlds)

    def observe(self, oracle: bool = False) -> Observation:
        obs = [w.observe(oracle=oracle) for w in self.worlds]
        if len(obs) == 1:
            return obs[0]
        nxt = None if not oracle else np.concatenate([o.next_humans for o in obs])
        return Observation(
            np.concatenate([o.robot for o in obs]),
            np.concatenate([o.humans for o in obs]),
            np.concatenate([o.human_mask for o in obs]),
            np.concatenate([o.active for o in obs]),
            np.concatenate([o.time for o in obs]),
            obs[0].dt,
            obs[0].kinematics,
            nxt,
        )

    def step(self, actions: np.ndarray) -> MultiStep:
        """Steps every world; the ``final_*`` arrays hold each slot's state right after the step
        (before the auto-reset of finished slots)."""
        parts = []
        for w, lo, hi in zip(self.worlds, self.offsets[:-1], self.offsets[1:], strict=True):
            res = w.step(actions[lo:hi], final_observation=True, observe=True)
            obs = res.observation
            robot, humans, mask, time = obs.robot, obs.humans, obs.human_mask, obs.time
            done = np.flatnonzero(res.terminated | res.truncated)
            if done.size:
                fo = res.final_observation
                robot[done], humans[done], mask[done], time[done] = (
                    fo.robot,
                    fo.humans,
                    fo.human_mask,
                    fo.time,
                )
            parts.append((res.reward, res.terminated, res.truncated, robot, humans, mask, time))
        cat = [np.concatenate([p[i] for p in parts]) for i in range(7)]
        return MultiStep(*cat)
