"""The training scenario mix as one batch: one World per scenario, stepped together.

``MultiWorld`` concatenates the observations of its worlds so that the policy scores every slot of
every scenario in one call, and splits the actions back. Scenarios whose design fixes the crowd (one
person head-on in a hallway, a standing group) keep their own human count, as in evaluation; the
worlds' human slots are then zero-padded to the largest count (mask False). The episodes' obstacles
come with the observation (``obstacles``) and with the state after each step (``final_maps``).

Also what a trainer's checkpoints record of the world they were trained in: the reward constants
(:func:`reward_config`) and an actor checkpoint's ``ppo_policy`` record (:func:`ppo_policy_config`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from socialnav.presets import Preset
from socialnav.scenarios import make_scenario
from socialnav.scenarios.registry import get_scenario
from socialnav.sim.observation import Observation, ObstacleArrays
from socialnav.sim.world import World


def training_n_humans(preset: Preset, policy: str, cadrl_one_human: bool = True) -> int:
    """Humans per training episode.

    The preset's, or 1 for a policy whose record asks for it (CADRL, trained with one human, as its
    authors did) while ``cadrl_one_human`` is on. Scenarios that fix their own crowd keep it
    (:func:`scenario_crowd`).

    Args:
        preset: the preset.
        policy: the learned policy's name.
        cadrl_one_human: the training setting.

    Returns:
        The number of humans.
    """
    from socialnav.policies.learned_catalog import get_learned_spec, learned_policy_names

    if cadrl_one_human and policy in learned_policy_names() and get_learned_spec(policy).one_human_training:
        return 1
    return int(preset.training.n_humans)


def scenario_crowd(name: str, n_humans: int) -> dict[str, int]:
    """The ``n_humans`` keyword for scenario ``name``.

    None where the scenario fixes its own crowd (the francis2023 scenarios with one person or a
    standing group refuse any other count).

    Args:
        name: a registered scenario.
        n_humans: the crowd asked for.

    Returns:
        ``{"n_humans": n}`` or ``{}``.
    """
    return {} if get_scenario(name).fixed_n_humans else {"n_humans": int(n_humans)}


def concat_optional(scans: list) -> np.ndarray | None:
    """The worlds' per-slot arrays (lidar scans, robot twists) back to back (None where they have none)."""
    return None if scans[0] is None else np.concatenate(scans)


def mix_human_slots(preset: Preset, n_humans: int) -> int:
    """Human slots of the training mix's observations.

    The largest crowd among its scenarios: a fixed one (:func:`scenario_crowd`) or ``n_humans``.

    Args:
        preset: the preset (its training mix).
        n_humans: the crowd of scenarios that take one.

    Returns:
        The number of slots.
    """
    import dataclasses as dc

    def crowd(name: str) -> int:
        cls = get_scenario(name)
        if not cls.fixed_n_humans:
            return int(n_humans)
        return int(next(f.default for f in dc.fields(cls) if f.name == "n_humans"))

    return max(crowd(name) for name in preset.training.scenarios)


def trains_among_walls(preset: Preset) -> bool:
    """Whether the preset's training mix has a scenario with walls.

    Args:
        preset: the preset.

    Returns:
        True when one of its training scenarios is a walled one.
    """
    from socialnav.scenarios.walls import WalledScenario

    return any(issubclass(get_scenario(name), WalledScenario) for name in preset.training.scenarios)


def obstacle_encoding_entry(preset: Preset) -> dict[str, Any]:
    """The obstacle encoding a network trained under ``preset`` reads, as its checkpoint records it.

    Both trainers decide by it (docs/walls_learned.md): a training mix with walls gives the default
    ``ObstaclePoints()``; without walls the entry is absent, as in every checkpoint written before, so
    that open-floor runs keep their records and resume.

    Args:
        preset: the preset trained under.

    Returns:
        ``{"obstacle_encoding": ObstaclePoints().to_dict()}`` among walls, else ``{}``.
    """
    if not trains_among_walls(preset):
        return {}
    from socialnav.sim.obstacle_points import ObstaclePoints

    return {"obstacle_encoding": ObstaclePoints().to_dict()}


def check_observation_parts(policy: str) -> None:
    """Refuses to train a learned policy whose record observes other parts than the trainers build.

    Both trainers build the networks' inputs of :data:`~socialnav.sim.parts.NETWORK_PARTS` (their replay
    memory and rollout buffers hold the human and obstacle point slots); evaluation composes any parts.

    Raises:
        ConfigError: naming the record's parts and the ones training builds.
    """
    from socialnav.policies.learned_catalog import get_learned_spec
    from socialnav.settings import ConfigError
    from socialnav.sim.parts import NETWORK_PARTS

    parts = get_learned_spec(policy).observation_parts
    if parts != NETWORK_PARTS:
        raise ConfigError(f"policy {policy!r} observes {', '.join(parts)}: training builds the networks' "
                          f"inputs of {', '.join(NETWORK_PARTS)} only (docs/extending.md)")


def pad_humans(humans: np.ndarray, mask: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(B, m, 5), (B, m) zero-padded to n >= m human slots (mask False)."""
    m = humans.shape[1]
    if m == n:
        return humans, mask
    return (np.concatenate([humans, np.zeros((humans.shape[0], n - m, humans.shape[2]))], axis=1),
            np.concatenate([mask, np.zeros((mask.shape[0], n - m), dtype=bool)], axis=1))


def _concat_obstacles(parts: list[ObstacleArrays | None], sizes: list[int]) -> ObstacleArrays | None:
    if all(p is None for p in parts):
        return None
    maps = [m for p, size in zip(parts, sizes, strict=True)
            for m in (p.maps if p is not None else [None] * size)]
    return ObstacleArrays.from_maps(maps)


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
    final_maps: tuple | None = None  # (B,) the stepped episodes' StaticMap or None; None: open floors


class MultiWorld:
    """Worlds of the scenario mix stepped in lockstep.

    Args:
        preset: world semantics, robot and training scenario mix.
        n_humans: humans per episode (scenarios that fix their own crowd keep it).
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
        """Builds one world per scenario of the training mix (see the class's arguments)."""
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
        if count is None and batch_size < len(names):
            import warnings

            warnings.warn(f"{batch_size} environment slot(s) for {len(names)} training scenarios: stepping "
                          f"{len(names)}, one per scenario (raise n_envs / the batch to at least "
                          f"{len(names)} to choose)", UserWarning, stacklevel=2)
        self.worlds: list[World] = []
        for name, size, cnt in zip(names, sizes, counts, strict=True):
            if cnt == 0:
                continue
            scenario = make_scenario(
                name, **scenario_crowd(name, n_humans), robot_v_pref=preset.robot.v_pref,
                robot_radius=preset.robot.radius,
            )
            b = size if cnt is None else max(1, min(size, cnt))
            self.worlds.append(
                World(settings, scenario, b, split=split, start=start, count=cnt, record=False)
            )
        self.sizes = [w.batch_size for w in self.worlds]
        self.offsets = np.cumsum([0, *self.sizes])
        self.batch_size = int(self.offsets[-1])
        self.dt = settings.dt
        #: human slots of every observation: the largest crowd of the mix (mix_human_slots)
        self.n_human_slots = max(w.n_agents - 1 for w in self.worlds)

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
        """Whether a world is still stepping in the background."""
        return any(w.busy for w in self.worlds)

    def observe(self, oracle: bool = False) -> Observation:
        """Every world's observation, concatenated (humans padded to the mix's slots).

        Args:
            oracle: include the humans' true next states.

        Returns:
            The observation of every slot.
        """
        obs = [w.observe(oracle=oracle) for w in self.worlds]
        if len(obs) == 1:
            return obs[0]
        n = self.n_human_slots
        padded = [pad_humans(o.humans, o.human_mask, n) for o in obs]
        nxt = None
        if oracle:
            nxt = np.concatenate([pad_humans(o.next_humans, o.human_mask, n)[0] for o in obs])
        return Observation(
            np.concatenate([o.robot for o in obs]),
            np.concatenate([h for h, _ in padded]),
            np.concatenate([m for _, m in padded]),
            np.concatenate([o.active for o in obs]),
            np.concatenate([o.time for o in obs]),
            obs[0].dt,
            obs[0].kinematics,
            nxt,
            _concat_obstacles([o.obstacles for o in obs], self.sizes),
            lidar=concat_optional([o.lidar for o in obs]),
            robot_twist=concat_optional([o.robot_twist for o in obs]),
        )

    def step(self, actions: np.ndarray) -> MultiStep:
        """Steps every world once.

        The ``final_*`` arrays hold each slot's state right after the step (before the auto-reset
        of finished slots).

        Args:
            actions: (B, 2) one action per slot.

        Returns:
            The step's rewards, outcomes and final states.
        """
        parts, walls = [], []
        for w, lo, hi in zip(self.worlds, self.offsets[:-1], self.offsets[1:], strict=True):
            stepped = tuple(w.static_maps)  # before the refill of finished slots
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
            humans, mask = pad_humans(humans, mask, self.n_human_slots)
            parts.append((res.reward, res.terminated, res.truncated, robot, humans, mask, time))
            walls.extend(stepped)
        cat = [np.concatenate([p[i] for p in parts]) for i in range(7)]
        return MultiStep(*cat, tuple(walls) if any(m is not None for m in walls) else None)


def reward_config(world: Any) -> dict[str, float]:
    """The reward constants a checkpoint records for ``world``.

    The evaluator compares them (policies/learned_loading.py).

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


def ppo_policy_config(preset: Preset) -> dict[str, Any]:
    """The world the actor is trained for (checked against the preset at evaluation).

    A preset whose training mix has walls adds the obstacle encoding the network reads
    (:func:`~socialnav.train.worlds.obstacle_encoding_entry`, as for the value-based trainer).

    Args:
        preset: the preset trained under.

    Returns:
        Plain data: kinematics, rotation limit, dt, reward constants (and ``obstacle_encoding``, and a
        differential drive's limits ``diff_drive``).
    """
    w = preset.world
    return {
        "kinematics": w.kinematics,
        "rotation_limit": w.rotation_limit,
        "dt": w.dt,
        "reward": reward_config(w),
        **obstacle_encoding_entry(preset),
        # a differential drive's actions span its speeds, reversing included (attn_graph.squash_actions)
        **({"diff_drive": w.diff_drive.to_dict()} if w.kinematics == "diff_drive" else {}),
        # a unicycle's actions span its commands (records without the key are older ones, which clipped)
        **({"action_squash": "span"} if w.kinematics == "unicycle" else {}),
    }
