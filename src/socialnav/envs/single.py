"""The Gymnasium environment of one episode at a time over the batched world (B = 1).

Observations are dicts composed of named observation parts (:mod:`socialnav.envs.config`: by default
``robot`` (9,), ``humans`` (N, 5), ``human_mask`` (N,), and with walls ``obstacles`` (E, 4) and
``obstacle_mask`` (E,)). Actions are continuous (vx, vy) or (v, dθ) by default, or an index into
CrowdSim's 81-action set with ``action_set="discrete"``.

Episodes are named by their index in the chosen split (``info["episode_index"]``) and played in
an order an :class:`EpisodeOrder` fixes:

- ``reset(seed=s)`` starts the stream of seed s: episodes ``s·10⁷, s·10⁷+1, …`` of an endless
  split (train), or, where the episodes are finite (a single-human sweep's 20, or the 1000 of the
  val/test splits), a permutation of them drawn from s, a new permutation each time round (cycling).
  Distinct seeds give distinct streams, so the copies of ``gym.make_vec(..., "sync"/"async")``
  (seeded s, s+1, …, or from entropy with ``seed=None``) never replay each other's episodes.
- ``reset(options={"index": k})`` plays episodes k, k+1, … (wrapping round a finite set): replays
  episode k exactly.
- ``reset()`` continues the current stream (a fresh random one on the first call).

The native vector env (:mod:`socialnav.envs.vector`) plays the same stream B episodes at a time.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from socialnav.envs.config import EnvConfig, check_options, maps_of
from socialnav.envs.episode_order import EpisodeOrder
from socialnav.envs.render import available_render_modes
from socialnav.maps.static_map import StaticMap
from socialnav.sim.observation import Observation
from socialnav.sim.settings import WorldSettings
from socialnav.sim.world import World

__all__ = ["SocialNavEnv"]


class SocialNavEnv(gym.Env):
    """One crowd-navigation episode at a time (the batched world with B = 1).

    Args:
        scenario: Registered scenario name (``circle_crossing`` …).
        scenario_params: Scenario fields (``n_humans`` …).
        world: World settings (dict or WorldSettings).
        split: Episode split ("train", "val", "test").
        action_set: "continuous" or "discrete" (CrowdSim's 81 actions).
        preset: A protocol preset (name, YAML path or Preset): its world settings, robot, crowd size
            (and, for the single-human sweeps, repeats); ``scenario_params``/``world`` override it.
        render_mode: None, "rgb_array" (``render()`` returns the frame) or "human" (a window, where
            a display exists); drawn by socialnav.viz (needs the ``viz`` extra).
        static_map: One map for every episode: a StaticMap, its dict form or a map file (YAML or
            SVG, :func:`socialnav.maps.files.load_map`). A scenario with walls of its own keeps its maps.
        max_obstacle_edges: Edges in the observation's ``obstacles`` (zero-padded); default: the
            most an episode's map can have (the map's, or the walled scenario's bound).
        observation_parts: The observation's named parts, in order (default
            :data:`~socialnav.envs.config.RAW_PARTS`: ``robot``, ``humans``, ``obstacle_edges``, then
            ``lidar`` where the world has one and ``robot_twist`` for a differential drive); it must hold
            ``robot`` and ``humans``. A part registered from outside the package adds its keys.
    """

    metadata = {"render_modes": available_render_modes(), "render_fps": 4}

    def __init__(
        self,
        scenario: str = "circle_crossing",
        scenario_params: dict | None = None,
        world: dict | WorldSettings | None = None,
        split: str = "train",
        action_set: str = "continuous",
        preset: Any = None,
        render_mode: str | None = None,
        static_map: StaticMap | dict | str | os.PathLike | None = None,
        max_obstacle_edges: int | None = None,
        observation_parts: Sequence[str] | None = None,
    ):
        self._recorder = None
        if render_mode is not None:
            from socialnav.envs.render import EnvRecorder, check_render_mode

            check_render_mode(render_mode)
            self._recorder = EnvRecorder()
        self.render_mode = render_mode
        self._cfg = EnvConfig(scenario, scenario_params, world, split, action_set, preset, static_map,
                              max_obstacle_edges, observation_parts)
        self._world = World(self._cfg.settings, self._cfg.scenario, 1, split=split, record=False,
                            static_map=self._cfg.static_map)
        self.observation_maps: tuple = ()
        self._order: EpisodeOrder | None = None
        self._position = 0
        self.observation_space, self.action_space = self._cfg.spaces()

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Start the next episode of the stream (Gymnasium's ``reset``).

        Args:
            seed: Seeds the episode order (one stream; see the module docstring).
            options: ``{"index": i}`` plays episode i next and continues from there.

        Returns:
            (tuple): The first observation and the info dict.
        """
        super().reset(seed=seed)
        options = check_options(options)
        if "index" in options:
            self._order, self._position = self._cfg.order(start=int(options["index"])), 0
        elif seed is not None or self._order is None:
            stream_seed = seed if seed is not None else int(self.np_random.integers(2**32))
            self._order, self._position = self._cfg.order(seed=stream_seed), 0
        obs = self._world.use_stream(self._cfg.stream(self._order, self._position, 1))
        self._position += 1
        single = self._single(obs)
        #: (1,) the static map of the observation last returned (the learner wrappers encode it)
        self.observation_maps = maps_of(obs)
        index = int(self._world.episode_index[0])
        if self._recorder is not None:
            self._recorder.start(self._world, single, index)
            self.metadata = {**self.metadata, "render_fps": 1.0 / self._cfg.settings.dt}
            if self.render_mode == "human":
                self.render()
        return single, self._info("running", float(self._world.dmin[0]), 0.0, index)

    def step(self, action):
        """Apply one action (Gymnasium's ``step``).

        Args:
            action (Any): The robot's action in the env's action space.

        Returns:
            (tuple): ``(observation, reward, terminated, truncated, info)``.

        Raises:
            RuntimeError: The episode is over and ``reset()`` was not called.
        """
        if not self._world.busy:
            raise RuntimeError("the episode is over: call reset() before step()")
        result = self._world.step(self._cfg.to_actions(action), final_observation=True)
        terminated, truncated = bool(result.terminated[0]), bool(result.truncated[0])
        w = self._world
        if terminated or truncated:
            # The finished episode's values: the world has already emptied its slot.
            obs = result.final_observation
            info = self._info(result.outcome[0], float(result.final_dmin[0]), float(obs.time[0]),
                              int(result.final_episode[0]), result.collision_kind[0])
        else:
            obs = w.observe()
            info = self._info("running", float(w.dmin[0]), float(w.steps[0] * w.settings.dt),
                              int(w.episode_index[0]))
        single = self._single(obs)
        self.observation_maps = maps_of(obs)
        if self._recorder is not None:
            self._recorder.record(single, info["outcome"])
            if self.render_mode == "human":
                self.render()
        return single, float(result.reward[0]), terminated, truncated, info

    def render(self):
        """The current episode so far as an RGB array (``rgb_array``), or shown in a window (``human``)."""
        if self._recorder is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' to make()")
            return None
        if not self._recorder.positions:
            raise RuntimeError("render() before reset(): nothing to draw yet")
        if self.render_mode == "human":
            self._recorder.show(self.metadata["render_fps"])
            return None
        return self._recorder.frame()

    def close(self) -> None:
        """Closes the render window, if any, and stops the world's native threads now."""
        recorder = getattr(self, "_recorder", None)  # absent when __init__ failed
        if recorder is not None:
            recorder.close()
        if getattr(self, "_world", None) is not None:
            self._world.close()
        super().close()

    def _single(self, obs: Observation) -> dict[str, np.ndarray]:
        return {k: v[0] for k, v in self._cfg.observation(obs).items()}

    @staticmethod
    def _info(
        outcome: str, dmin: float, time: float, episode_index: int, collision_kind: str = ""
    ) -> dict[str, Any]:
        return {"outcome": outcome, "dmin": dmin, "time": time, "episode_index": episode_index,
                "collision_kind": collision_kind}
