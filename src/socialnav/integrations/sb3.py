"""Stable-Baselines3 on the native vector env: one native call steps every environment, no subprocesses.

>>> from stable_baselines3 import PPO
>>> from socialnav.integrations.sb3 import SocialNavVecEnv, save_model
>>> venv = SocialNavVecEnv("socialnav/CircleCrossing-v0", num_envs=64, preset="wang2022")
>>> model = PPO("MultiInputPolicy", venv).learn(100_000)
>>> save_model(model, "ppo_circle.zip")   # then: socialnav evaluate --policy sb3:ppo_circle.zip

:class:`SocialNavVecEnv` follows SB3's ``VecEnv`` contract: ``reset()`` returns the batched
observation (and keeps ``reset_infos``); ``step`` returns ``(obs, rewards, dones, infos)`` where a
finished slot's obs is already the next episode's first and its info holds ``terminal_observation``,
``TimeLimit.truncated`` (ended by the time limit, not by success or collision), ``is_success`` (SB3
logs it as ``rollout/success_rate``) and the episode's ``outcome``, ``time``, ``dmin`` and
``episode_index``. All slots share one episode stream: ``seed(s)`` (or ``PPO(..., seed=s)``) makes
the next ``reset()`` start stream s, so a seed reproduces a rollout; ``reset()`` without a new seed
continues the stream and never replays an episode. Add SB3's ``VecMonitor`` for episode returns and
lengths in the logs.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

try:
    from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper
except ImportError as err:  # the optional extra is missing: say which one
    raise ImportError(
        f"socialnav.integrations.sb3 needs stable-baselines3: pip install 'socialnav[sb3]' ({err})"
    ) from None

from socialnav.envs.learner_wrappers import make_transform, observation_maps, training_record
from socialnav.envs.registration import ENV_IDS
from socialnav.envs.vector import SocialNavVectorEnv
from socialnav.sim.learner_obs import ObservationSettings
from socialnav.sim.observation import ROBOT_DIM
from socialnav.sim.parts.base import sensor_arrays

#: Attribute of an SB3 model under which :func:`save_model` stores the training record (SB3 saves
#: a model's plain attributes in the zip's ``data`` JSON and restores them on load).
RECORD_ATTRIBUTE = "socialnav_record"


class SocialNavVecEnv(VecEnv):
    """SB3 ``VecEnv`` over :class:`~socialnav.envs.vector.SocialNavVectorEnv`.

    Args:
        env: A registered id (``"socialnav/CircleCrossing-v0"`` …), a scenario name, or a built
            SocialNavVectorEnv (then no ``env_kwargs``).
        num_envs: Episodes stepped in lockstep.
        observation: The learner's observation (float32, world frame, the env's human count by
            default); see :mod:`socialnav.sim.learner_obs`.
        **env_kwargs: What ``gym.make`` takes for the id: ``scenario_params``, ``world``, ``split``,
            ``action_set``, ``preset``.
    """

    def __init__(
        self,
        env: str | SocialNavVectorEnv = "socialnav/CircleCrossing-v0",
        num_envs: int = 16,
        *,
        observation: ObservationSettings | None = None,
        **env_kwargs: Any,
    ):
        if isinstance(env, SocialNavVectorEnv):
            if env_kwargs:
                raise ValueError(f"a built vector env takes no further settings, got {sorted(env_kwargs)}")
            self.venv = env
        else:
            if env in ENV_IDS:
                env_kwargs = {**ENV_IDS[env], **env_kwargs}
            elif "/" not in env:
                env_kwargs = {"scenario": env, **env_kwargs}
            else:
                raise ValueError(f"unknown env id {env!r}; valid: {', '.join(ENV_IDS)}, or a scenario name")
            if "render_mode" in env_kwargs:
                raise ValueError(
                    "SocialNavVecEnv does not render; use gym.make(..., render_mode='rgb_array')"
                )
            self.venv = SocialNavVectorEnv(num_envs, **env_kwargs)
        self._cfg = self.venv._cfg
        self.transform = make_transform(self._cfg, observation)
        self._robot = np.zeros((self.venv.num_envs, ROBOT_DIM))
        self._actions: np.ndarray | None = None
        super().__init__(self.venv.num_envs, self.transform.single_space(), self.venv.single_action_space)

    # -- the VecEnv contract ----------------------------------------------------------------------
    def reset(self):
        """Reset every slot (the seeds and options set by ``seed()``/``set_options()`` apply once).

        Returns:
            The converted observations of all slots.
        """
        seed = self._seeds[0]
        options = self._options[0] or None
        obs, info = self.venv.reset(seed=None if seed is None else int(seed), options=options)
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = [{"episode_index": int(info["episode_index"][b])} for b in range(self.num_envs)]
        return self._convert(obs)

    def step_async(self, actions: np.ndarray) -> None:
        """Store the actions (n_envs, 2) the next ``step_wait()`` applies.

        Raises:
            ValueError: Not one action of the action space per env (the shapes are named).
        """
        actions = np.asarray(actions)
        expected = (self.num_envs, *self.action_space.shape)
        if actions.shape != expected:
            raise ValueError(f"actions of shape {actions.shape}: expected {expected} (one action of the "
                             f"action space per env, {self.num_envs} envs)")
        self._actions = actions

    def step_wait(self):
        """Step every slot with the stored actions, auto-resetting finished ones.

        Returns:
            Observations, rewards (n_envs,), dones (n_envs,) and one info dict per slot (SB3's layout; a
                finished slot's ``terminal_observation`` is in its info).

        Raises:
            RuntimeError: No ``step_async()`` came before.
        """
        if self._actions is None:
            raise RuntimeError("step_wait() without step_async()")
        actions = self.transform.actions_to_world(self._actions, self._robot)
        self._actions = None
        obs, reward, terminated, truncated, info = self.venv.step(actions)
        dones = terminated | truncated
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        if dones.any():
            done = np.flatnonzero(dones)
            finals = [info["final_obs"][b] for b in done]
            reads_maps = self.transform.composition.reads_maps
            terminal = self.transform(
                np.stack([f["robot"] for f in finals]),
                np.stack([f["humans"] for f in finals]),
                np.stack([f["human_mask"] for f in finals]),
                [self.venv.final_observation_maps[int(b)] for b in done] if reads_maps else None,
                {k: np.stack([f[k] for f in finals]) for k in sensor_arrays(finals[0])},
            )
            final_info = info["final_info"]
            for k, b in enumerate(done):
                outcome = final_info["outcome"][b]
                infos[b] = {
                    "terminal_observation": {key: value[k] for key, value in terminal.items()},
                    "TimeLimit.truncated": bool(truncated[b] and not terminated[b]),
                    "is_success": outcome == "success",
                    "outcome": outcome,
                    "time": float(final_info["time"][b]),
                    "dmin": float(final_info["dmin"][b]),
                    "episode_index": int(final_info["episode_index"][b]),
                }
        return self._convert(obs), reward.astype(np.float32), dones, infos

    def close(self) -> None:
        """Close the native vector env."""
        self.venv.close()

    def seed(self, seed: int | None = None) -> list[int | None]:
        """The stream every slot plays from the next ``reset()`` (one stream, so one seed for all)."""
        seeds = super().seed(seed)
        self._seeds = [seeds[0]] * self.num_envs
        return self._seeds

    def get_attr(self, attr_name: str, indices: Iterable[int] | int | None = None) -> list[Any]:
        """An attribute of the native vector env, the same for every slot.

        The slots share one world; ``render_mode`` is None.
        """
        n = len(self._indices(indices))
        if attr_name == "render_mode":
            return [None] * n
        if attr_name.startswith("_") or not hasattr(self.venv, attr_name):
            raise AttributeError(f"SocialNavVectorEnv has no attribute {attr_name!r}")
        return [getattr(self.venv, attr_name)] * n

    def set_attr(self, attr_name: str, value: Any, indices: Iterable[int] | int | None = None) -> None:
        """Refused: the slots share one native world whose settings are fixed when it is built.

        Raises:
            NotImplementedError: Always, naming the attribute.
        """
        raise NotImplementedError(
            f"set_attr({attr_name!r}): the slots share one native world, whose settings are fixed when it "
            "is built; build a new SocialNavVecEnv with the setting instead"
        )

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        """Call ``training_record`` (the same for every slot).

        Other per-env methods do not exist here, since the slots are rows of one native world, not env
        objects.
        """
        n = len(self._indices(indices))
        if method_name == "training_record":
            return [self.training_record()] * n
        raise NotImplementedError(
            f"env_method({method_name!r}): the slots are rows of one native world, not env objects; "
            "use the vector env's own methods (SocialNavVecEnv.venv)"
        )

    def env_is_wrapped(self, wrapper_class: type, indices=None) -> list[bool]:
        """Whether each slot is wrapped in ``wrapper_class``: never (the slots are not env objects)."""
        return [False] * len(self._indices(indices))

    def get_images(self):
        """Refused: the vector env does not render.

        Raises:
            NotImplementedError: Always; ``gym.make(..., render_mode='rgb_array')`` renders one episode.
        """
        raise NotImplementedError(
            "SocialNavVecEnv does not render; use gym.make(..., render_mode='rgb_array')"
        )

    # -- socialnav --------------------------------------------------------------------------------
    def training_record(self) -> dict[str, Any]:
        """What a model trained here records (:func:`save_model`) to be evaluated the same way."""
        return training_record(self._cfg, self.transform)

    def _convert(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        self._robot = np.array(obs["robot"], dtype=np.float64)
        # each slot's own walls (a scenario's, or the env's static_map), as the evaluation gives them
        return self.transform(obs["robot"], obs["humans"], obs["human_mask"],
                              observation_maps(self.venv, self.transform), sensor_arrays(obs))

    def _indices(self, indices: Iterable[int] | int | None) -> list[int]:
        if indices is None:
            return list(range(self.num_envs))
        return [indices] if isinstance(indices, int | np.integer) else list(indices)


def find_training_record(env: Any) -> dict[str, Any]:
    """The training record of the env a model was trained on.

    The env is a SocialNavVecEnv (through any SB3 wrappers such as VecMonitor or VecNormalize), or SB3's
    Dummy/SubprocVecEnv of single envs wrapped in
    :class:`~socialnav.envs.learner_wrappers.LearnerObservation`.
    """
    while isinstance(env, VecEnvWrapper):
        env = env.venv
    if isinstance(env, SocialNavVecEnv):
        return env.training_record()
    if isinstance(env, VecEnv):
        try:
            return env.env_method("training_record", indices=[0])[0]
        except AttributeError:
            pass
    raise ValueError(
        f"cannot tell how {type(env).__name__} converts observations: train on SocialNavVecEnv, or on "
        "single envs wrapped in socialnav.envs.learner_wrappers.LearnerObservation"
    )


def save_model(model: Any, path: str | Path, env: Any = None) -> Path:
    """Save ``model`` (``model.save``) with the record of the env it was trained on.

    The record holds how its env converted observations, its action space and world, so that ``socialnav
    evaluate --policy sb3:PATH`` converts the same way and refuses a world the model was not trained for.

    Args:
        model: An SB3 algorithm (PPO, SAC, …).
        path: The ``.zip`` to write.
        env: The training env, if not ``model.get_env()``.
    """
    record = find_training_record(env if env is not None else model.get_env())
    record["algorithm"] = type(model).__name__
    record["algorithm_module"] = type(model).__module__.split(".")[0]
    setattr(model, RECORD_ATTRIBUTE, record)
    path = Path(path)
    model.save(path)
    return path if path.suffix else path.with_suffix(".zip")  # SB3 adds .zip to a bare name
