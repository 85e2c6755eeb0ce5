"""Gymnasium environments over the batched world: one episode (Env) and B episodes (VectorEnv).

Observations are dicts of arrays: ``robot`` (9,), ``humans`` (N, 5) and ``human_mask`` (N,)
(see :mod:`socialnav.sim.observation`). Actions are continuous (vx, vy) or (v, dθ) by default,
or an index into CrowdSim's 81-action set with ``action_set="discrete"``. Episodes are named by
their index in the chosen split: ``reset(seed=k)`` starts at episode k, later resets continue with
k+1, k+2, …, so a seed reproduces an episode exactly.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from socialnav.config import from_dict
from socialnav.scenarios import make_scenario
from socialnav.sim.actions import discrete_actions
from socialnav.sim.observation import Observation
from socialnav.sim.settings import WorldSettings
from socialnav.sim.world import World
from socialnav.viz.env_render import available_render_modes

OUTCOME_CODES = {"running": 0, "success": 1, "collision": 2, "timeout": 3}


def _spaces(n_humans: int, settings: WorldSettings, v_pref: float, action_set: str):
    big = np.float64(1e6)
    observation_space = spaces.Dict(
        {
            "robot": spaces.Box(-big, big, shape=(9,), dtype=np.float64),
            "humans": spaces.Box(-big, big, shape=(n_humans, 5), dtype=np.float64),
            "human_mask": spaces.MultiBinary(n_humans),
        }
    )
    if action_set == "discrete":
        action_space: spaces.Space = spaces.Discrete(81)
    elif settings.kinematics == "holonomic":
        action_space = spaces.Box(-v_pref, v_pref, shape=(2,), dtype=np.float64)
    else:
        action_space = spaces.Box(
            np.array([-v_pref, -settings.rotation_limit]),
            np.array([v_pref, settings.rotation_limit]),
            dtype=np.float64,
        )
    return observation_space, action_space


def _obs_rows(obs: Observation) -> dict[str, np.ndarray]:
    return {"robot": obs.robot, "humans": obs.humans, "human_mask": obs.human_mask.astype(np.int8)}


class _EnvConfig:
    """Shared construction of the world's settings and scenario from keyword arguments."""

    def __init__(
        self,
        scenario: str,
        scenario_params: dict | None,
        world: dict | WorldSettings | None,
        split: str,
        action_set: str,
    ):
        if action_set not in ("continuous", "discrete"):
            raise ValueError(f"action_set must be 'continuous' or 'discrete', got {action_set!r}")
        self.settings = (
            world if isinstance(world, WorldSettings) else from_dict(WorldSettings, world, "world")
        )
        self.scenario = make_scenario(scenario, **(scenario_params or {}))
        self.split = split
        self.action_set = action_set
        self.v_pref = float(self.scenario.robot_v_pref)
        self.table = discrete_actions(self.settings.kinematics, self.v_pref, self.settings.rotation_limit)

    def to_actions(self, action: np.ndarray) -> np.ndarray:
        if self.action_set == "discrete":
            index = np.asarray(action, dtype=np.int64).reshape(-1)
            if np.any((index < 0) | (index >= len(self.table))):
                raise ValueError(f"discrete action out of range [0, {len(self.table)}): {index}")
            return self.table[index]
        return np.asarray(action, dtype=np.float64).reshape(-1, 2)


class SocialNavEnv(gym.Env):
    """One crowd-navigation episode at a time (the batched world with B = 1).

    Args:
        scenario: Registered scenario name (``circle_crossing`` …).
        scenario_params: Scenario fields (``n_humans`` …).
        world: World settings (dict or WorldSettings).
        split: Episode split ("train", "val", "test").
        action_set: "continuous" or "discrete" (CrowdSim's 81 actions).
        render_mode: None, "rgb_array" (``render()`` returns the frame) or "human" (a window, where
            a display exists); drawn by socialnav.viz (needs the ``viz`` extra).
    """

    metadata = {"render_modes": available_render_modes(), "render_fps": 4}

    def __init__(
        self,
        scenario: str = "circle_crossing",
        scenario_params: dict | None = None,
        world: dict | WorldSettings | None = None,
        split: str = "train",
        action_set: str = "continuous",
        render_mode: str | None = None,
    ):
        self._recorder = None
        if render_mode is not None:
            from socialnav.viz.env_render import EnvRecorder, check_render_mode

            check_render_mode(render_mode)
            self._recorder = EnvRecorder()
        self.render_mode = render_mode
        self._cfg = _EnvConfig(scenario, scenario_params, world, split, action_set)
        self._world = World(self._cfg.settings, self._cfg.scenario, 1, split=split, record=False)
        self._next_index = 0
        self.observation_space, self.action_space = _spaces(
            self._cfg.scenario.n_humans, self._cfg.settings, self._cfg.v_pref, action_set
        )

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        if options and "index" in options:
            self._next_index = int(options["index"])
        elif seed is not None:
            self._next_index = int(seed)
        obs = self._world.restart(self._next_index)
        self._next_index += 1
        single = self._single(obs)
        if self._recorder is not None:
            self._recorder.start(self._world, single, self._next_index - 1)
            self.metadata = {**self.metadata, "render_fps": 1.0 / self._cfg.settings.dt}
            if self.render_mode == "human":
                self.render()
        return single, self._info(outcome="running")

    def step(self, action):
        result = self._world.step(self._cfg.to_actions(action), final_observation=True)
        terminated, truncated = bool(result.terminated[0]), bool(result.truncated[0])
        if terminated or truncated:
            obs = result.final_observation
            outcome = result.outcome[0]
        else:
            obs = self._world.observe()
            outcome = "running"
        single = self._single(obs)
        if self._recorder is not None:
            self._recorder.record(single, outcome)
            if self.render_mode == "human":
                self.render()
        return single, float(result.reward[0]), terminated, truncated, self._info(outcome)

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
        if getattr(self, "_recorder", None) is not None:
            self._recorder.close()
        if getattr(self, "_world", None) is not None:
            self._world.close()
        super().close()

    def _single(self, obs: Observation) -> dict[str, np.ndarray]:
        return {k: v[0] for k, v in _obs_rows(obs).items()}

    def _info(self, outcome: str) -> dict[str, Any]:
        w = self._world
        return {
            "outcome": outcome,
            "dmin": float(w.dmin[0]),
            "time": float(w.steps[0] * w.settings.dt),
            "episode_index": self._next_index - 1,
        }


class SocialNavVectorEnv(VectorEnv):
    """B episodes stepped natively in lockstep; finished ones reset in the same step.

    Follows Gymnasium's ``AutoresetMode.SAME_STEP``: when an episode ends, the returned observation
    is the first of the next episode and ``info["final_obs"]`` / ``info["final_info"]`` hold the
    finished one's. ``info`` values are arrays of shape (num_envs,).
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
    ):
        self._cfg = _EnvConfig(scenario, scenario_params, world, split, action_set)
        self.num_envs = int(num_envs)
        self._world = World(self._cfg.settings, self._cfg.scenario, self.num_envs, split=split, record=False)
        self.single_observation_space, self.single_action_space = _spaces(
            self._cfg.scenario.n_humans, self._cfg.settings, self._cfg.v_pref, action_set
        )
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        if seed is not None:
            self._np_random, self._np_random_seed = gym.utils.seeding.np_random(seed)
        start = int(options["index"]) if options and "index" in options else int(seed or 0)
        obs = self._world.restart(start)
        return _obs_rows(obs), {"episode_index": self._world.episode_index.copy()}

    def close_extras(self, **kwargs: Any) -> None:
        """Stops the world's native threads now (called by ``VectorEnv.close``)."""
        if getattr(self, "_world", None) is not None:
            self._world.close()

    def step(self, actions):
        result = self._world.step(self._cfg.to_actions(actions), final_observation=True)
        obs = _obs_rows(self._world.observe())
        done = result.terminated | result.truncated
        info: dict[str, Any] = {
            "dmin": self._world.dmin.copy(),
            "episode_index": self._world.episode_index.copy(),
        }
        if done.any():
            final = np.empty(self.num_envs, dtype=object)
            rows = _obs_rows(result.final_observation)
            for k, b in enumerate(np.flatnonzero(done)):
                final[b] = {key: value[k] for key, value in rows.items()}
            info["final_obs"] = final
            info["_final_obs"] = done.copy()
        return obs, result.reward, result.terminated, result.truncated, info
