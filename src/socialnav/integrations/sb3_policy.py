"""``sb3:PATH``: a saved Stable-Baselines3 model as a protocol policy.

Used as ``socialnav evaluate --policy sb3:model.zip``.

The model's zip carries the record :func:`socialnav.integrations.sb3.save_model` wrote: the observation
conversion of its training env, its action set, kinematics, robot speed and world. Loading checks the
model against the preset it is evaluated under and refuses, naming both sides, a model whose action
space, kinematics or observation setting differ; a different dt is refused too unless
``--allow-preset-mismatch`` (then recorded). A model saved with plain ``model.save`` has no record: it is
accepted only when its observation space is the raw env's (world frame, SI units), whose conversion is
then known, and its algorithm must be named (``--policy-arg algo=PPO``).

Actions are the model's deterministic ones (``predict(..., deterministic=True)``). The model file's
SHA-256 is part of ``describe()``, hence of the run's manifest: a run resumed after the file changed is
refused, and ``socialnav replay`` refuses to replay with another file.
"""

from __future__ import annotations

import hashlib
import importlib
import io
import json
import math
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from socialnav.sim.learner_obs import HUMAN_COLUMNS, ROBOT_COLUMNS, ObservationSettings, ObservationTransform
from socialnav.sim.learner_wrappers import RECORD_FORMAT
from socialnav.sim.observation import Observation

PREFIX = "sb3:"
ALGORITHM_MODULES = ("stable_baselines3", "sb3_contrib")
#: ``--policy-arg`` keys: the algorithm, the torch device, and observation settings, which must
#: repeat the model's record (a way to state what is expected).
PARAMETERS = {"algo": None, "device": "cpu", **{k: None for k in ObservationSettings().to_dict()}}


class SB3ModelError(ValueError):
    """A model file that cannot be evaluated as asked (the message names the file and both sides)."""


class SB3Policy:
    """A loaded SB3 model acting deterministically on the learner's observation of each episode."""

    information = "none"

    def __init__(
        self,
        spec: str,
        data: bytes,
        model: Any,
        record: dict[str, Any],
        device: str,
        inferred: bool,
        preset_mismatch: list[str],
    ):
        self.spec = spec
        self.path = spec[len(PREFIX) :]
        self.name = "sb3-" + (Path(self.path).stem or "model")
        self.record = record
        self.inferred = inferred
        self.device = device
        self.preset_mismatch = preset_mismatch
        self.sha256 = hashlib.sha256(data).hexdigest()
        self._data = data
        self._algorithm = type(model)
        self.model = model
        settings = ObservationSettings.from_dict(record["observation"])
        self.transform = ObservationTransform(
            settings, settings.max_humans, record["kinematics"], record["action_set"]
        )
        self._table = None
        if record["action_set"] == "discrete":
            from socialnav.sim.actions import discrete_actions

            self._table = discrete_actions(
                record["kinematics"], record["robot_v_pref"], record["rotation_limit"]
            )

    def act(self, observation: Observation) -> np.ndarray:
        """The model's actions for the active episodes, converted to world-frame velocities.

        Args:
            observation: The world's observation of B episodes.

        Returns:
            (B, 2) float64 velocities [m/s]; zero for inactive episodes.
        """
        actions = np.zeros((observation.batch_size, 2))
        rows = np.flatnonzero(observation.active)
        if rows.size == 0:
            return actions
        robot = observation.robot[rows]
        walls = observation.obstacles
        maps = [None] * rows.size if walls is None else [walls.maps[int(b)] for b in rows]
        obs = self.transform(robot, observation.humans[rows], observation.human_mask[rows], maps)
        chosen, _ = self.model.predict(obs, deterministic=True)
        if self._table is not None:
            actions[rows] = self._table[np.asarray(chosen, dtype=np.int64).reshape(-1)]
        else:
            actions[rows] = self.transform.actions_to_world(
                np.asarray(chosen, np.float64).reshape(-1, 2), robot
            )
        return actions

    def describe(self) -> dict[str, Any]:
        """The record stored with results: policy spec, information, model path and training record."""
        return {
            "policy": self.spec,
            "information": self.information,
            "model": self.path,
            "sha256": self.sha256,
            "algorithm": self._algorithm.__name__,
            "device": self.device,
            "deterministic": True,
            "observation": self.transform.settings.to_dict(),
            "action_set": self.record["action_set"],
            "record": "inferred" if self.inferred else "saved",
            **({"preset_mismatch_allowed": self.preset_mismatch} if self.preset_mismatch else {}),
        }

    # Simulation workers get the exact bytes that were hashed, not whatever the path holds by then.
    def __getstate__(self) -> dict[str, Any]:
        return {k: v for k, v in self.__dict__.items() if k != "model"}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self.model = self._algorithm.load(io.BytesIO(self._data), device=self.device)


def load_sb3_policy(
    spec: str,
    preset: Any,
    *,
    algo: str | None = None,
    device: str = "cpu",
    allow_preset_mismatch: bool = False,
    **observation: Any,
) -> SB3Policy:
    """The policy ``sb3:PATH`` evaluated under ``preset``.

    Raises:
        SB3ModelError: Not a readable model, no algorithm known, or a model trained for another
            action space, kinematics, observation setting or (unless allowed) dt than asked.
    """
    path = Path(spec[len(PREFIX) :] if spec.startswith(PREFIX) else spec)
    if not str(path):
        raise SB3ModelError("policy sb3:PATH needs the path of a model file, e.g. sb3:runs/ppo.zip")
    unknown = sorted(set(observation) - set(PARAMETERS))
    if unknown:
        raise SB3ModelError(
            f"policy {spec}: no parameter(s) {', '.join(unknown)}; valid: {', '.join(PARAMETERS)}"
        )
    _require_sb3(spec)
    if path.is_dir():
        found = sorted(p.name for p in path.glob("*.zip"))
        hint = f" (it holds {', '.join(found[:5])}{' …' if len(found) > 5 else ''})" if found else ""
        raise SB3ModelError(f"policy {spec}: {path} is a directory; give the model's .zip file{hint}")
    if not path.is_file():
        raise SB3ModelError(f"policy {spec}: model file {path} does not exist")
    data = path.read_bytes()
    saved = _read_saved_data(path, data)
    record = saved.get("socialnav_record")
    inferred = record is None
    algorithm = _algorithm(path, algo, None if inferred else record.get("algorithm"))
    try:
        model = algorithm.load(io.BytesIO(data), device=device)
    except Exception as err:  # SB3 raises many kinds; the user's fix is the same: file or algorithm
        raise SB3ModelError(
            f"{path}: cannot be loaded as {algorithm.__name__} ({type(err).__name__}: {err})"
        ) from None
    if inferred:
        record = _infer_record(path, model, preset)
    elif not isinstance(record, dict) or record.get("format") != RECORD_FORMAT:
        raise SB3ModelError(
            f"{path}: socialnav record of an unknown format ({str(record)[:80]}); "
            "save it again with socialnav.integrations.sb3.save_model"
        )
    mismatch = _check(path, model, record, preset, {k: v for k, v in observation.items() if v is not None})
    if mismatch and not allow_preset_mismatch:
        raise SB3ModelError(
            f"{path} was trained for another world: {'; '.join(mismatch)}; evaluate it under "
            "a matching preset, or pass --allow-preset-mismatch (recorded in the results)"
        )
    return SB3Policy(
        spec if spec.startswith(PREFIX) else f"{PREFIX}{path}",
        data,
        model,
        record,
        device,
        inferred,
        mismatch,
    )


def _require_sb3(spec: str) -> None:
    try:
        import stable_baselines3  # noqa: F401
    except ImportError:
        raise SB3ModelError(f"policy {spec} needs stable-baselines3: pip install 'socialnav[sb3]'") from None


def _read_saved_data(path: Path, data: bytes) -> dict[str, Any]:
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            return json.loads(archive.read("data").decode())
    except (zipfile.BadZipFile, KeyError, ValueError, UnicodeDecodeError) as err:
        raise SB3ModelError(f"{path} is not a Stable-Baselines3 model zip ({err})") from None


def _algorithm(path: Path, asked: str | None, recorded: str | None) -> type:
    if asked and recorded and asked != recorded:
        raise SB3ModelError(
            f"{path}: algorithm {asked!r} asked (--policy-arg algo), {recorded!r} in the model file"
        )
    name = asked or recorded
    if not name:
        raise SB3ModelError(
            f"{path} does not record its algorithm (saved without socialnav.integrations.sb3.save_model): "
            "name it with --policy-arg algo=PPO (or SAC, A2C, TD3, ...)"
        )
    for module_name in ALGORITHM_MODULES:
        try:
            module = importlib.import_module(module_name)
        except ImportError:
            continue
        from stable_baselines3.common.base_class import BaseAlgorithm

        cls = getattr(module, str(name), None)
        if isinstance(cls, type) and issubclass(cls, BaseAlgorithm):
            return cls
    raise SB3ModelError(f"{path}: unknown algorithm {name!r} (looked in {', '.join(ALGORITHM_MODULES)})")


def _infer_record(path: Path, model: Any, preset: Any) -> dict[str, Any]:
    """The record of a model saved without one, when its observation space is the raw env's."""
    space = model.observation_space
    keys = set(getattr(space, "spaces", {}) or {})
    raw = (
        keys == {"robot", "humans", "human_mask"}
        and space["robot"].shape == (len(ROBOT_COLUMNS["world"]),)
        and space["humans"].shape[1:] == (len(HUMAN_COLUMNS["world"]),)
    )
    if not raw:
        raise SB3ModelError(
            f"{path} carries no socialnav record and its observation space {space} is not the raw env's, so "
            "how it converted observations is unknown: save it with socialnav.integrations.sb3.save_model"
        )
    world = preset.world
    discrete = type(model.action_space).__name__ == "Discrete"
    return {
        "format": RECORD_FORMAT,
        "observation": ObservationSettings(
            max_humans=int(space["humans"].shape[0]), dtype=str(np.dtype(space["humans"].dtype))
        ).to_dict(),
        "action_set": "discrete" if discrete else "continuous",
        # not recorded: the action space check below stands for them
        "kinematics": world.kinematics,
        "rotation_limit": world.rotation_limit,
        "robot_v_pref": preset.robot.v_pref,
        "dt": world.dt,
    }


def _check(path: Path, model: Any, record: dict[str, Any], preset: Any, asked: dict[str, Any]) -> list[str]:
    """Refuses hard mismatches (both sides named); returns the allowable ones (dt, walls it cannot see)."""
    from socialnav.policies.learned_entries import walled_scenarios
    from socialnav.sim.env import observation_and_action_spaces

    world = preset.world
    where = f"preset {preset.name!r}"
    settings = ObservationSettings.from_dict(record["observation"]).to_dict()
    for key, value in asked.items():
        if key in settings and value != settings[key]:
            raise SB3ModelError(
                f"{path}: observation setting {key} = {settings[key]!r} in the model file, {value!r} asked; "
                "a model only understands the observation it was trained on"
            )
    if record["kinematics"] != world.kinematics:
        raise SB3ModelError(
            f"{path}: kinematics {record['kinematics']!r} in the model file, {world.kinematics!r} in {where}"
        )
    v_pref = float(preset.robot.v_pref)
    _, expected_actions = observation_and_action_spaces(1, world, v_pref, record["action_set"])
    if not _same_space(model.action_space, expected_actions):
        raise SB3ModelError(
            f"{path}: action space {_show(model.action_space)} of the model, {_show(expected_actions)} for "
            f"{record['action_set']} {world.kinematics} actions at v_pref {preset.robot.v_pref} under {where}"
        )
    transform = ObservationTransform(
        ObservationSettings(**settings), settings["max_humans"], world.kinematics, record["action_set"]
    )
    expected_obs = transform.single_space()
    if not _same_space(model.observation_space, expected_obs):
        raise SB3ModelError(
            f"{path}: observation space {_show(model.observation_space)} of the model, {_show(expected_obs)} "
            f"from its recorded observation setting {settings}"
        )
    mismatch = []
    if not math.isclose(float(record["dt"]), world.dt, rel_tol=1e-9):
        mismatch.append(f"dt {record['dt']!r} in the model file, {world.dt!r} in {where}")
    walled = walled_scenarios((*preset.evaluation.multi_human, *preset.evaluation.single_human))
    if walled and not settings.get("obstacle_points"):
        # as for the project's checkpoints trained without walls: the model's input has no obstacles
        mismatch.append(
            f"walls: the model's observation has no obstacle points (obstacle_points = 0), {where} evaluates "
            f"scenarios with walls ({', '.join(walled)}) that it cannot see"
        )
    return mismatch


def _same_space(a: Any, b: Any) -> bool:
    if type(a).__name__ != type(b).__name__:
        return False
    if hasattr(a, "spaces") and isinstance(a.spaces, dict):
        return set(a.spaces) == set(b.spaces) and all(_same_space(a[k], b[k]) for k in a.spaces)
    if type(a).__name__ == "Box":
        return (
            a.shape == b.shape
            and a.dtype == b.dtype
            and np.allclose(a.low, b.low)
            and np.allclose(a.high, b.high)
        )
    if type(a).__name__ == "Discrete":
        return int(a.n) == int(b.n)
    return getattr(a, "shape", None) == getattr(b, "shape", None)


def _show(space: Any) -> str:
    if hasattr(space, "spaces") and isinstance(space.spaces, dict):
        return "{" + ", ".join(f"{k}: {_show(v)}" for k, v in sorted(space.spaces.items())) + "}"
    if type(space).__name__ == "Box":
        low, high = np.unique(space.low), np.unique(space.high)
        bounds = (
            f"[{low[0]:g}, {high[0]:g}]"
            if low.size == 1 and high.size == 1
            else f"[{np.array2string(space.low, precision=3)}, {np.array2string(space.high, precision=3)}]"
        )
        return f"Box{bounds} {space.shape} {np.dtype(space.dtype).name}"
    return str(space)
