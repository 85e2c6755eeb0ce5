"""Gymnasium environments over the batched world: one episode (Env) and B episodes (VectorEnv).

Observations are dicts of arrays: ``robot`` (9,), ``humans`` (N, 5) and ``human_mask`` (N,)
(see :mod:`socialnav.sim.observation`), and in worlds with walls (``max_obstacle_edges`` > 0)
``obstacles`` (E, 4), the episode's obstacle edges (x1, y1, x2, y2), zero-padded, and
``obstacle_mask`` (E,). Actions are continuous (vx, vy) or (v, dθ) by default,
or an index into CrowdSim's 81-action set with ``action_set="discrete"``.

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

The native vector env plays the same stream B episodes at a time; its ``info`` has the layout
Gymnasium's own ``SyncVectorEnv`` gives (``key`` / ``_key`` masks, ``final_obs``, ``final_info``).
"""

from __future__ import annotations

import dataclasses
import os
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from socialnav.config import from_dict
from socialnav.maps.static_map import StaticMap
from socialnav.scenarios import make_scenario
from socialnav.scenarios.base import SPLIT_SIZE
from socialnav.sim.actions import discrete_actions
from socialnav.sim.env_render import available_render_modes
from socialnav.sim.episode_order import EpisodeOrder
from socialnav.sim.observation import Observation
from socialnav.sim.settings import WorldSettings
from socialnav.sim.world import EpisodeStream, StepResult, World, walls_win_message

OUTCOME_CODES = {"running": 0, "success": 1, "collision": 2, "timeout": 3}


def observation_and_action_spaces(
    n_humans: int, settings: WorldSettings, v_pref: float, action_set: str, max_edges: int = 0
):
    """The env's observation and action spaces (a SB3 model's saved spaces are checked against them)."""
    big = np.float64(1e6)
    entries: dict[str, spaces.Space] = {
        "robot": spaces.Box(-big, big, shape=(9,), dtype=np.float64),
        "humans": spaces.Box(-big, big, shape=(n_humans, 5), dtype=np.float64),
        # Gymnasium has no MultiBinary(0): a crowd-free scenario's empty mask is an empty Box
        "human_mask": spaces.MultiBinary(n_humans) if n_humans else spaces.Box(0, 1, (0,), np.int8),
    }
    if max_edges:
        entries["obstacles"] = spaces.Box(-big, big, shape=(max_edges, 4), dtype=np.float64)
        entries["obstacle_mask"] = spaces.MultiBinary(max_edges)
    observation_space = spaces.Dict(entries)
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


def _obs_rows(obs: Observation, max_edges: int = 0) -> dict[str, np.ndarray]:
    rows = {"robot": obs.robot, "humans": obs.humans, "human_mask": obs.human_mask.astype(np.int8)}
    if max_edges:
        b = obs.batch_size
        if obs.obstacles is None:
            rows["obstacles"] = np.zeros((b, max_edges, 4))
            rows["obstacle_mask"] = np.zeros((b, max_edges), dtype=np.int8)
        else:
            edges, mask = obs.obstacles.padded_edges(max_edges)
            rows["obstacles"], rows["obstacle_mask"] = edges.copy(), mask.astype(np.int8)
    return rows


def _maps_of(obs: Observation) -> tuple:
    """(B,) each row's static map (None: open floor), for wrappers that encode the walls themselves."""
    return obs.obstacles.maps if obs.obstacles is not None else (None,) * obs.batch_size


class _EnvConfig:
    """Shared construction of the world's settings and scenario from keyword arguments."""

    def __init__(
        self,
        scenario: str,
        scenario_params: dict | None,
        world: dict | WorldSettings | None,
        split: str,
        action_set: str,
        preset: Any = None,
        static_map: StaticMap | dict | str | os.PathLike | None = None,
        max_obstacle_edges: int | None = None,
    ):
        if action_set not in ("continuous", "discrete"):
            raise ValueError(f"action_set must be 'continuous' or 'discrete', got {action_set!r}")
        if isinstance(static_map, dict):
            static_map = StaticMap.from_dict(static_map)
        elif isinstance(static_map, str | os.PathLike):
            from socialnav.maps.files import load_map

            static_map = load_map(os.fspath(static_map))
        if static_map is not None and not isinstance(static_map, StaticMap):
            raise TypeError(
                "static_map must be a StaticMap, its dict form, a map file path or None, got "
                f"{type(static_map).__name__}"
            )
        self.static_map = static_map or None
        if max_obstacle_edges is not None and (
            not isinstance(max_obstacle_edges, int | np.integer) or max_obstacle_edges < 0
        ):
            raise ValueError(f"max_obstacle_edges must be an integer >= 0, got {max_obstacle_edges!r}")
        if preset is not None:
            scenario_params, world = _preset_defaults(preset, scenario, scenario_params, world)
        self.settings = (
            world if isinstance(world, WorldSettings) else from_dict(WorldSettings, world, "world")
        )
        if self.settings.continue_after_success:
            # The protocol's M_III continuation runs the humans on after the robot's success, with the
            # robot parked: an env's episode is the robot's, which ends at its success.
            raise ValueError("world.continue_after_success: the evaluation's M_III continuation, not an "
                             "environment setting (an env episode ends at the robot's success); leave it "
                             "false")
        self.scenario = make_scenario(scenario, **(scenario_params or {}))
        # A scenario with walls of its own (which win over static_map, as in World) bounds its maps' edges.
        own = int(getattr(self.scenario, "max_obstacle_edges", 0))
        if own and self.static_map is not None:
            import warnings

            warnings.warn(walls_win_message(scenario), UserWarning, stacklevel=3)
            self.static_map = None  # said once, here: the World is not given it
        edges = own if own else (0 if self.static_map is None else len(self.static_map.edges()[0]))
        #: The episodes have walls: the observation should show them.
        self.has_walls = edges > 0
        if max_obstacle_edges is None:
            max_obstacle_edges = edges
        if edges > max_obstacle_edges:
            whose = f"scenario {scenario!r}'s maps have up to" if own == edges else "static_map has"
            raise ValueError(f"{whose} {edges} edges, more than max_obstacle_edges = {max_obstacle_edges}")
        self.max_edges = int(max_obstacle_edges)
        self.split = split
        self.action_set = action_set
        self.v_pref = float(self.scenario.robot_v_pref)
        self.table = discrete_actions(self.settings.kinematics, self.v_pref, self.settings.rotation_limit)
        # Episodes available: a finite scenario's set, the val/test split's range, or endless (train).
        n = self.scenario.n_episodes
        if n is not None and split != "train" and n > SPLIT_SIZE:  # refused here, not at episode 1000
            raise ValueError(f"scenario {scenario!r} has {n} episodes, more than the {SPLIT_SIZE} of split "
                             f"{split!r} (fewer repeats, or split='train')")
        self.n_episodes = n if n is not None else (None if split == "train" else SPLIT_SIZE)

    def order(self, *, seed: int | None = None, start: int | None = None) -> EpisodeOrder:
        return EpisodeOrder(self.n_episodes, seed=seed, start=start)

    def stream(self, order: EpisodeOrder, position: int, count: int | None = None) -> EpisodeStream:
        return EpisodeStream(self.scenario, self.split, position, count, index_map=order)

    def to_actions(self, action: Any, n_envs: int | None = None) -> np.ndarray:
        """The world's (B, 2) actions from one env's action (``n_envs`` None) or a vector env's.

        The shape must be the action space's ((2,) or an index; (n_envs, 2) or (n_envs,) for a vector
        env); a discrete index must be an integer, not a float or bool that would be cast silently.
        """
        if action is None:
            raise ValueError("action is None: step() needs an action of the env's action space")
        raw = np.asarray(action)
        if self.action_set == "discrete":
            expected: tuple[int, ...] = () if n_envs is None else (n_envs,)
            if raw.shape != expected and not (n_envs is None and raw.shape == (1,)):
                raise ValueError(f"discrete action of shape {raw.shape}: expected {expected or 'a scalar'} "
                                 "(action indices)")
            if raw.dtype.kind not in "iu":
                raise ValueError(f"discrete action {action!r}: expected integer indices, got {raw.dtype}")
            index = raw.astype(np.int64).reshape(-1)
            if np.any((index < 0) | (index >= len(self.table))):
                raise ValueError(f"discrete action out of range [0, {len(self.table)}): {index}")
            return self.table[index]
        expected = (2,) if n_envs is None else (n_envs, 2)
        if raw.shape != expected:
            raise ValueError(f"action of shape {raw.shape}: expected {expected} (the action space's shape"
                             + ("" if n_envs is None else ", one action per env") + ")")
        try:
            return raw.astype(np.float64).reshape(-1, 2)
        except (TypeError, ValueError):
            raise ValueError(f"action {action!r}: expected numbers, got {raw.dtype}") from None


def _preset_defaults(preset: Any, scenario: str, scenario_params: dict | None, world: Any):
    """Scenario parameters and world settings of a protocol preset (explicit arguments win)."""
    from socialnav.presets import Preset, load_preset

    p = preset if isinstance(preset, Preset) else load_preset(preset)
    default = make_scenario(scenario)
    single = scenario in p.evaluation.single_human or default.n_episodes is not None
    params: dict[str, Any] = {"robot_v_pref": p.robot.v_pref, "robot_radius": p.robot.radius}
    if single:
        params.update(n_humans=1, repeats=p.evaluation.repeats)
    elif not default.fixed_n_humans:  # as the evaluation's cells: a designed crowd keeps its own count
        params["n_humans"] = p.evaluation.n_humans
    params.update(scenario_params or {})
    if world is None:
        world = p.world
    elif not isinstance(world, WorldSettings):
        world = {**dataclasses.asdict(p.world), **dict(world)}
    return params, world


def _check_options(options: dict[str, Any] | None) -> dict[str, Any]:
    options = dict(options or {})
    unknown = sorted(set(options) - {"index"})
    if unknown:
        raise ValueError(f"unknown reset option(s) {', '.join(unknown)}; valid: index")
    return options


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
    ):
        self._recorder = None
        if render_mode is not None:
            from socialnav.sim.env_render import EnvRecorder, check_render_mode

            check_render_mode(render_mode)
            self._recorder = EnvRecorder()
        self.render_mode = render_mode
        self._cfg = _EnvConfig(scenario, scenario_params, world, split, action_set, preset, static_map,
                               max_obstacle_edges)
        self._world = World(self._cfg.settings, self._cfg.scenario, 1, split=split, record=False,
                            static_map=self._cfg.static_map)
        self.observation_maps: tuple = ()
        self._order: EpisodeOrder | None = None
        self._position = 0
        self.observation_space, self.action_space = observation_and_action_spaces(
            self._cfg.scenario.n_humans, self._cfg.settings, self._cfg.v_pref, action_set, self._cfg.max_edges
        )

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Start the next episode of the stream (Gymnasium's ``reset``).

        Args:
            seed: Seeds the episode order (one stream; see the module docstring).
            options: ``{"index": i}`` plays episode i next and continues from there.

        Returns:
            (tuple): The first observation and the info dict.
        """
        super().reset(seed=seed)
        options = _check_options(options)
        if "index" in options:
            self._order, self._position = self._cfg.order(start=int(options["index"])), 0
        elif seed is not None or self._order is None:
            stream_seed = seed if seed is not None else int(self.np_random.integers(2**32))
            self._order, self._position = self._cfg.order(seed=stream_seed), 0
        obs = self._world.use_stream(self._cfg.stream(self._order, self._position, 1))
        self._position += 1
        single = self._single(obs)
        #: (1,) the static map of the observation last returned (the learner wrappers encode it)
        self.observation_maps = _maps_of(obs)
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
        self.observation_maps = _maps_of(obs)
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
        return {k: v[0] for k, v in _obs_rows(obs, self._cfg.max_edges).items()}

    @staticmethod
    def _info(
        outcome: str, dmin: float, time: float, episode_index: int, collision_kind: str = ""
    ) -> dict[str, Any]:
        return {"outcome": outcome, "dmin": dmin, "time": time, "episode_index": episode_index,
                "collision_kind": collision_kind}


class SocialNavVectorEnv(VectorEnv):
    """B episodes stepped natively in lockstep; finished ones reset in the same step.

    Follows Gymnasium's ``AutoresetMode.SAME_STEP``: when an episode ends, the returned observation
    is the first of the next episode and ``info["final_obs"]`` / ``info["final_info"]`` hold the
    finished one's (``final_info["outcome"]``, ``["time"]``, ``["dmin"]``, ``["episode_index"]``,
    ``["collision_kind"]``, each with its ``_key`` mask). ``info["outcome"]`` etc. describe the
    episodes now in the slots. The layout is the one ``gym.make_vec(..., vectorization_mode="sync")``
    gives.
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
    ):
        self._cfg = _EnvConfig(scenario, scenario_params, world, split, action_set, preset, static_map,
                               max_obstacle_edges)
        self.num_envs = int(num_envs)
        self._world = World(self._cfg.settings, self._cfg.scenario, self.num_envs, split=split,
                            record=False, static_map=self._cfg.static_map)
        self.observation_maps: tuple = ()
        self.final_observation_maps: dict[int, Any] = {}
        self._order: EpisodeOrder | None = None
        self.single_observation_space, self.single_action_space = observation_and_action_spaces(
            self._cfg.scenario.n_humans, self._cfg.settings, self._cfg.v_pref, action_set, self._cfg.max_edges
        )
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
        options = _check_options(options)
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
        self.observation_maps, self.final_observation_maps = _maps_of(obs), {}
        return _obs_rows(obs, self._cfg.max_edges), self._current_info()

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
        obs = _obs_rows(result.observation, self._cfg.max_edges)
        self.observation_maps, self.final_observation_maps = _maps_of(result.observation), {}
        done = result.terminated | result.truncated
        info = self._current_info()
        if done.any():
            final = np.full(self.num_envs, None, dtype=object)
            rows = _obs_rows(result.final_observation, self._cfg.max_edges)
            final_maps = _maps_of(result.final_observation)
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
