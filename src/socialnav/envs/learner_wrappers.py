"""Gymnasium wrappers applying :class:`~socialnav.sim.learner_obs.ObservationSettings`: the learner's parts.

They wrap the single env and the native vector env, converting exactly as the SB3 adapter does
(docs/train_your_own.md).

>>> env = LearnerObservation(gym.make("socialnav/CircleCrossing-v0"), ObservationSettings(frame="robot"))

Both wrappers keep the env's action space; with ``frame="robot"`` and a holonomic robot the action
is read in the robot frame and rotated to the world frame before it is stepped. Each offers
``training_record()``: what a saved model must remember to be evaluated with the same conversion.
"""

from __future__ import annotations

import warnings
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import VectorWrapper
from gymnasium.vector.utils import batch_space

from socialnav.sim.learner_obs import ObservationSettings, ObservationTransform
from socialnav.sim.parts.base import sensor_arrays

#: Version of the record a saved model carries (socialnav.integrations.sb3).
RECORD_FORMAT = 1


def env_config(env: Any) -> Any:
    """The construction settings of a socialnav env (single or vector, wrapped or not)."""
    raw = env.unwrapped
    cfg = getattr(raw, "_cfg", None)
    if cfg is None:
        raise TypeError(
            f"{type(raw).__name__} is not a socialnav env: wrap gym.make('socialnav/...') or "
            "SocialNavVectorEnv"
        )
    return cfg


def make_transform(cfg: Any, settings: ObservationSettings | dict[str, Any] | None) -> ObservationTransform:
    """The observation transform of a world configuration ``cfg`` under ``settings``.

    ``settings`` may be a dict of :class:`ObservationSettings` fields (as ``world=`` takes a dict). Warns
    (UserWarning) where the episodes have walls and ``settings`` shows none of them.

    Raises:
        ConfigError: A dict with an unknown field or a bad value (named).
        TypeError: ``settings`` is neither.
        ValueError: A part the learner's layout cannot give, or that reads a sensor key the raw env's
            ``observation_parts`` lack (named).
    """
    if isinstance(settings, dict):
        settings = ObservationSettings.from_dict(settings)
    elif settings is not None and not isinstance(settings, ObservationSettings):
        raise TypeError(f"observation settings must be an ObservationSettings or a dict of its fields, got "
                        f"{type(settings).__name__}")
    settings = settings or ObservationSettings()
    transform = ObservationTransform(
        settings, cfg.scenario.n_humans, cfg.settings.kinematics, cfg.action_set,
        static_map=getattr(cfg, "static_map", None), sensing=cfg.settings.sensing,
    )
    raw = getattr(cfg, "composition", None)
    missing = [] if raw is None else [k for k in transform.composition.sensor_keys if k not in raw.spaces()]
    if missing:
        raise ValueError(
            f"the learner's observation parts {list(settings.parts)} read the raw env's key(s) "
            f"{', '.join(missing)}, which the env does not give: its observation_parts {list(cfg.parts)} "
            f"lack {', '.join(repr(k) for k in missing)} (add them, or leave observation_parts unset: the "
            "default adds the world's sensors)"
        )
    if getattr(cfg, "has_walls", False) and not transform.composition.shows_walls:
        warnings.warn(
            f"scenario {cfg.scenario.name!r} has walls, but none of the learner's observation parts "
            f"{list(settings.parts)} shows them (obstacle_points = {settings.obstacle_points}), so a policy "
            "trained on it cannot see the walls (set obstacle_points, e.g. 16, or add the part 'lidar'; "
            "docs/walls_learned.md)",
            stacklevel=3,
        )
    return transform


def observation_maps(env: Any, transform: ObservationTransform) -> Any:
    """Each row's static map in the observation ``env`` last returned, where the transform encodes walls.

    None (the transform's own map for every row) where none of its parts reads the walls
    (``ObservationPart.reads_maps``). The socialnav envs keep the maps of what they last returned;
    Gymnasium's vector envs of socialnav env copies are asked copy by copy (``get_attr``).
    """
    if not transform.composition.reads_maps:
        return None
    raw = env.unwrapped
    maps = getattr(raw, "observation_maps", None)
    if maps is not None:
        return maps
    if isinstance(raw, gym.vector.VectorEnv):  # Gymnasium's sync/async vector env of socialnav envs
        return [copy[0] for copy in raw.get_attr("observation_maps")]
    return None


def training_record(cfg: Any, transform: ObservationTransform) -> dict[str, Any]:
    """What evaluating a model trained on this env needs to know (JSON-ready)."""
    from socialnav import __version__

    world = cfg.settings
    return {
        "format": RECORD_FORMAT,
        "observation": transform.settings.to_dict(),
        "action_set": cfg.action_set,
        "kinematics": world.kinematics,
        "rotation_limit": world.rotation_limit,
        "dt": world.dt,
        "robot_v_pref": cfg.v_pref,
        "scenario": cfg.scenario.name,
        "n_humans": int(cfg.scenario.n_humans),
        "human_model": world.human_model,
        "visibility": world.visibility,
        "socialnav_version": __version__,
    } | ({} if world.sensing.is_default else {"sensing": world.sensing.to_dict()})


class LearnerObservation(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """The single env with the learner's observation (and robot-frame actions where that applies).

    It records its settings in the env's spec (Gymnasium's ``RecordConstructorArgs``), so that
    ``env.spec`` and ``check_env`` work on the wrapped env.
    """

    def __init__(self, env: gym.Env, settings: ObservationSettings | dict[str, Any] | None = None):
        gym.utils.RecordConstructorArgs.__init__(self, settings=settings)
        gym.Wrapper.__init__(self, env)
        self._cfg = env_config(env)
        self.transform = make_transform(self._cfg, settings)
        self.observation_space = self.transform.single_space()
        self._robot: np.ndarray | None = None  # raw robot row the next action is chosen on

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Reset the env and convert its observation.

        Returns:
            (tuple): The learner's observation and the env's info dict.
        """
        obs, info = self.env.reset(seed=seed, options=options)
        return self._convert(obs), info

    def step(self, action):
        """Step with the learner's action (rotated to the world frame where it is robot-frame).

        Returns:
            (tuple): ``(observation, reward, terminated, truncated, info)`` with the learner's observation.
        """
        if self._robot is not None and self.transform.rotates_actions:
            action = self.transform.actions_to_world(np.asarray(action)[None], self._robot[None])[0]
        obs, reward, terminated, truncated, info = self.env.step(action)
        return self._convert(obs), reward, terminated, truncated, info

    def training_record(self) -> dict[str, Any]:
        """The record of how this env converts observations, its action space and world."""
        return training_record(self._cfg, self.transform)

    def _convert(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        self._robot = np.array(obs["robot"], dtype=np.float64)
        sensors = {k: v[None] for k, v in sensor_arrays(obs).items()}
        out = self.transform(obs["robot"][None], obs["humans"][None], obs["human_mask"][None],
                             observation_maps(self.env, self.transform), sensors)
        return {k: v[0] for k, v in out.items()}


class LearnerObservationVector(VectorWrapper):
    """The vector env (native or ``sync``/``async``) with the learner's observation.

    ``final_obs`` of finished episodes is converted the same way.
    """

    def __init__(self, env: gym.vector.VectorEnv, settings: ObservationSettings | None = None):
        super().__init__(env)
        self._cfg = env_config(env) if hasattr(env.unwrapped, "_cfg") else _first_copy_config(env)
        self.transform = make_transform(self._cfg, settings)
        self.single_observation_space = self.transform.single_space()
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self._robot: np.ndarray | None = None

    def reset(self, *, seed: int | list[int] | None = None, options: dict[str, Any] | None = None):
        """Reset every slot and convert the observations.

        Returns:
            (tuple): The learner's batched observations and the env's info dict.
        """
        obs, info = self.env.reset(seed=seed, options=options)
        return self._convert(obs), info

    def step(self, actions):
        """Step with the learner's actions (rotated to the world frame where they are robot-frame).

        Returns:
            (tuple): ``(observations, rewards, terminations, truncations, infos)`` with the learner's
                observations, ``final_obs`` included.
        """
        if self._robot is not None and self.transform.rotates_actions:
            actions = self.transform.actions_to_world(actions, self._robot)
        obs, reward, terminated, truncated, info = self.env.step(actions)
        if "final_obs" in info:
            final = np.array(info["final_obs"], dtype=object)
            maps = self._final_maps()
            for b in np.flatnonzero(info["_final_obs"]):
                one = final[b]
                converted = self.transform(one["robot"][None], one["humans"][None], one["human_mask"][None],
                                           None if maps is None else [maps(int(b))],
                                           {k: v[None] for k, v in sensor_arrays(one).items()})
                final[b] = {k: v[0] for k, v in converted.items()}
            info = {**info, "final_obs": final}
        return self._convert(obs), reward, terminated, truncated, info

    def training_record(self) -> dict[str, Any]:
        """The record of how this env converts observations, its action space and world."""
        return training_record(self._cfg, self.transform)

    def _convert(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        self._robot = np.array(obs["robot"], dtype=np.float64)
        return self.transform(obs["robot"], obs["humans"], obs["human_mask"],
                              observation_maps(self.env, self.transform), sensor_arrays(obs))

    def _final_maps(self) -> Any:
        """Slot -> the static map of its ``final_obs`` (None: the transform's own map)."""
        if not self.transform.composition.reads_maps:
            return None
        finals = getattr(self.env.unwrapped, "final_observation_maps", None)
        if finals is not None:  # the native vector env
            return finals.__getitem__
        # env copies (autoreset in the same step): a copy's current map, the finished episode's where
        # its scenario's layout is fixed (every walled scenario but circle_crossing_obstacles)
        current = observation_maps(self.env, self.transform)
        return None if current is None else current.__getitem__


def _first_copy_config(env: gym.vector.VectorEnv) -> Any:
    # sync/async vector envs of gym.make copies: every copy is built from the same spec
    copies = getattr(env.unwrapped, "envs", None)
    if copies:
        return env_config(copies[0])
    spec = getattr(env.unwrapped, "spec", None)
    if spec is None:
        raise TypeError(f"{type(env.unwrapped).__name__} is not a vector env of socialnav envs")
    kwargs = {k: v for k, v in (spec.kwargs or {}).items() if k not in ("num_envs", "vectorization_mode")}
    probe = gym.make(spec.id, **kwargs)
    try:
        return env_config(probe)
    finally:
        probe.close()
