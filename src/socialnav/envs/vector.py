"""The Gymnasium vector environment: B episodes stepped natively in lockstep over one batched world.

It plays an env's episode stream (:mod:`socialnav.envs.single` explains seeds and indices) B episodes at a
time; its ``info`` has the layout Gymnasium's own ``SyncVectorEnv`` gives (``key`` / ``_key`` masks,
``final_obs``, ``final_info``). Observations are composed of named parts as the single env's are
(:mod:`socialnav.envs.config`).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from socialnav.envs.config import EnvConfig, check_options, maps_of
from socialnav.envs.episode_order import EpisodeOrder
from socialnav.maps.static_map import StaticMap
from socialnav.sim.settings import WorldSettings
from socialnav.sim.world import StepResult, World

__all__ = ["SocialNavVectorEnv"]


class SocialNavVectorEnv(VectorEnv):
    """B episodes stepped natively in lockstep; finished ones reset in the same step.

    Follows Gymnasium's ``AutoresetMode.SAME_STEP``: when an episode ends, the returned observation
    is the first of the next episode and ``info["final_obs"]`` / ``info["final_info"]`` hold the
    finished one's (``final_info["outcome"]``, ``["time"]``, ``["dmin"]``, ``["episode_index"]``,
    ``["collision_kind"]``, each with its ``_key`` mask). ``info["outcome"]`` etc. describe the
    episodes now in the slots. The layout is the one ``gym.make_vec(..., vectorization_mode="sync")``
    gives. The arguments are the single env's (:class:`~socialnav.envs.single.SocialNavEnv`) and
    ``num_envs``, the episodes stepped together.
    """

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP}

    def __init__(
        self,
        num_envs: int = 16,
        scenario: str = "circle_crossing",
        scenario_params: dict | None = None,
        world: dict | WorldSettings | None = None,
        split: str = "train",
        action_set: str = "continuous",
        preset: Any = None,
        static_map: StaticMap | dict | str | os.PathLike | None = None,
        max_obstacle_edges: int | None = None,
        observation_parts: Sequence[str] | None = None,
    ):
        self._cfg = EnvConfig(scenario, scenario_params, world, split, action_set, preset, static_map,
                              max_obstacle_edges, observation_parts)
        self.num_envs = int(num_envs)
        self._world = World(self._cfg.settings, self._cfg.scenario, self.num_envs, split=split,
                            record=False, static_map=self._cfg.static_map)
        self.observation_maps: tuple = ()
        self.final_observation_maps: dict[int, Any] = {}
        self._order: EpisodeOrder | None = None
        self.single_observation_space, self.single_action_space = self._cfg.spaces()
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Reset every slot to the next episodes of the shared stream (Gymnasium's vector ``reset``).

        Args:
            seed: One int: it names the stream all slots share.
            options: ``{"index": i}`` starts the stream at episode i.

        Returns:
            (tuple): The batched observations and the info dict.

        Raises:
            ValueError: ``seed`` is not one int.
        """
        options = check_options(options)
        if seed is not None and not isinstance(seed, int | np.integer):
            raise ValueError(f"seed must be one int (it names the stream all slots share), got {seed!r}")
        position = 0
        if seed is not None:
            self._np_random, self._np_random_seed = gym.utils.seeding.np_random(int(seed))
        if "index" in options:
            self._order = self._cfg.order(start=int(options["index"]))
        elif seed is not None or self._order is None:
            stream_seed = int(seed) if seed is not None else int(self.np_random.integers(2**32))
            self._order = self._cfg.order(seed=stream_seed)
        else:
            position = self._world.stream.next_index  # continue the stream: no episode twice
        obs = self._world.use_stream(self._cfg.stream(self._order, position))
        #: (n_envs,) each slot's static map in the observations last returned, and in ``final_obs``
        #: ({slot: map} of the last step's finished slots): the learner wrappers encode them
        self.observation_maps, self.final_observation_maps = maps_of(obs), {}
        return self._cfg.observation(obs), self._current_info()

    def close_extras(self, **kwargs: Any) -> None:
        """Stops the world's native threads now (called by ``VectorEnv.close``)."""
        if getattr(self, "_world", None) is not None:
            self._world.close()

    def step(self, actions):
        """Apply one action per slot; finished slots reset to the stream's next episodes.

        Args:
            actions (Any): (n_envs, ...) actions in the single action space's form.

        Returns:
            (tuple): ``(observations, rewards, terminations, truncations, infos)``; finished slots' last
                observations are in ``infos["final_obs"]``.
        """
        result = self._world.step(self._cfg.to_actions(actions, self.num_envs), final_observation=True,
                                  observe=True)
        obs = self._cfg.observation(result.observation)
        self.observation_maps, self.final_observation_maps = maps_of(result.observation), {}
        done = result.terminated | result.truncated
        info = self._current_info()
        if done.any():
            final = np.full(self.num_envs, None, dtype=object)
            rows = self._cfg.observation(result.final_observation)
            final_maps = maps_of(result.final_observation)
            for k, b in enumerate(np.flatnonzero(done)):
                final[b] = {key: value[k] for key, value in rows.items()}
                self.final_observation_maps[int(b)] = final_maps[k]
            info["final_obs"], info["_final_obs"] = final, done.copy()
            info["final_info"], info["_final_info"] = self._final_info(result, done), done.copy()
        return obs, result.reward, result.terminated, result.truncated, info

    def _current_info(self) -> dict[str, Any]:
        w = self._world
        outcome = np.full(self.num_envs, "running", dtype=object)
        return _masked(
            {
                "outcome": outcome,
                "dmin": w.dmin.copy(),
                "time": w.steps * w.settings.dt,
                "episode_index": w.episode_index.copy(),
                "collision_kind": np.full(self.num_envs, "", dtype=object),
            },
            np.ones(self.num_envs, dtype=bool),
        )

    def _final_info(self, result: StepResult, done: np.ndarray) -> dict[str, Any]:
        # Rows of slots that did not finish hold zeros/None, as SyncVectorEnv leaves them.
        outcome = np.full(self.num_envs, None, dtype=object)
        outcome[done] = result.outcome[done]
        collision_kind = np.full(self.num_envs, None, dtype=object)
        collision_kind[done] = result.collision_kind[done]
        final, final_dmin, final_episode = result.final_observation, result.final_dmin, result.final_episode
        if final is None or final_dmin is None or final_episode is None:
            raise RuntimeError("the step did not report its finished episodes (step with final_observation)")
        time = np.zeros(self.num_envs)
        time[np.flatnonzero(done)] = final.time
        return _masked(
            {
                "outcome": outcome,
                "dmin": np.where(done, final_dmin, 0.0),
                "time": time,
                "episode_index": np.where(done, final_episode, 0),
                "collision_kind": collision_kind,
            },
            done,
        )


def _masked(values: dict[str, np.ndarray], mask: np.ndarray) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in values.items():
        out[key], out[f"_{key}"] = value, mask.copy()
    return out
