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

Loading never runs code from the file. SB3's own ``load`` unpickles (cloudpickle) every field of the zip's
``data`` JSON marked ``:serialized:``, and unpickling can run anything. So every such field is rebuilt
here from socialnav's own knowledge and handed to SB3 as ``custom_objects``, which SB3 takes instead of
unpickling the field: the spaces from the record (or, without one, the raw env's under the preset), the
policy class from the algorithm's own policy aliases, ``policy_kwargs`` from known torch and SB3 classes,
and what only training needs (schedules, buffers, last observations) by constants. The readable parts SB3
writes beside each pickled field only select among and check these candidates. A pickled field that cannot
be rebuilt refuses the model before anything is unpickled; the weights (``*.pth``) are read by SB3 with
``torch.load(..., weights_only=True)``. docs/security.md lists what socialnav loads and how.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from socialnav.integrations.sb3_files import (
    SB3ModelError,
    algorithm_class,
    infer_record,
    load_model,
    read_saved_data,
    record_spaces,
    recorded_sensing,
    safe_custom_objects,
    same_space,
    saved_record,
    show_space,
)
from socialnav.sim.learner_obs import ObservationSettings, ObservationTransform
from socialnav.sim.observation import Observation
from socialnav.sim.parts.base import PartInput

PREFIX = "sb3:"
#: ``--policy-arg`` keys: the algorithm, the torch device, and observation settings, which must
#: repeat the model's record (a way to state what is expected).
PARAMETERS = {
    "algo": None, "device": "cpu", **{f.name: None for f in dataclasses.fields(ObservationSettings)}
}


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
        objects: dict[str, Any] | None = None,
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
        # what SB3 takes instead of unpickling the file's fields, again in every worker
        self._objects = objects or {}
        self.model = model
        settings = ObservationSettings.from_dict(record["observation"])
        sensing = recorded_sensing(record)
        self.transform = ObservationTransform(
            settings, settings.max_humans, record["kinematics"], record["action_set"], sensing=sensing,
        )
        #: The lidar the model reads, which it brings to the world it acts in (docs/perception.md).
        self.sensors = model_sensors(settings, sensing)
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
        sensors = {k: v[rows] for k, v in PartInput.from_observation(observation).sensors.items()}
        obs = self.transform(robot, observation.humans[rows], observation.human_mask[rows], maps, sensors)
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
            **({"sensors": dict(self.sensors)} if self.sensors else {}),
        }

    # Simulation workers get the exact bytes that were hashed, not whatever the path holds by then.
    def __getstate__(self) -> dict[str, Any]:
        return {k: v for k, v in self.__dict__.items() if k != "model"}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self.model = load_model(Path(self.path), self._algorithm, self._data, self._objects, self.device)


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

    Nothing in the file is unpickled: its pickled fields are rebuilt (see the module's docstring).

    Raises:
        SB3ModelError: Not a readable model, no algorithm known, a device this machine lacks, a record or
            pickled field socialnav cannot use or rebuild (named), or a model trained for another
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
    _check_device(spec, device)
    if path.is_dir():
        found = sorted(p.name for p in path.glob("*.zip"))
        hint = f" (it holds {', '.join(found[:5])}{' …' if len(found) > 5 else ''})" if found else ""
        raise SB3ModelError(f"policy {spec}: {path} is a directory; give the model's .zip file{hint}")
    if not path.is_file():
        raise SB3ModelError(f"policy {spec}: model file {path} does not exist")
    data = path.read_bytes()
    saved = read_saved_data(path, data)
    recorded = saved_record(path, saved)
    inferred = recorded is None
    algorithm = algorithm_class(path, algo, None if recorded is None else recorded.get("algorithm"))
    if recorded is None:
        record, spaces = infer_record(path, saved, preset)
    else:
        record, spaces = recorded, record_spaces(path, saved, recorded)
    objects = safe_custom_objects(path, saved, algorithm, *spaces)
    model = load_model(path, algorithm, data, objects, device)
    from socialnav.policies.learned_loading import perception_note

    note = perception_note(f"model {path}", record.get("sensing"), preset)
    if note:
        warnings.warn(note, UserWarning, stacklevel=2)
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
        objects,
    )


def model_sensors(settings: ObservationSettings, sensing: Any) -> dict[str, Any]:
    """The sensing settings a model brings (its lidar's beams, sector and range), {} for none.

    What its scan's layout and scale depend on; the noise of the returns stays the world's, as for
    ``lidar_ppo``.
    """
    from socialnav.sim.settings import LIDAR_GEOMETRY

    if "lidar" not in settings.parts or sensing is None or not sensing.lidar_beams:
        return {}
    return {key: getattr(sensing, key) for key in LIDAR_GEOMETRY}


def _require_sb3(spec: str) -> None:
    try:
        import stable_baselines3  # noqa: F401
    except ImportError:
        raise SB3ModelError(f"policy {spec} needs stable-baselines3: pip install 'socialnav[sb3]'") from None


def _check_device(spec: str, device: Any) -> None:
    """Refuses a torch device this machine lacks (SB3 would quietly fall back to the CPU)."""
    import torch

    try:
        chosen = torch.device(device)
    except (RuntimeError, TypeError) as err:
        raise SB3ModelError(
            f"policy {spec}: --policy-arg device={device!r} is not a torch device ({err})"
        ) from None
    kind = chosen.type
    backend = torch.backends.mps if kind == "mps" else getattr(torch, kind, None)
    available = kind == "cpu" or bool(getattr(backend, "is_available", lambda: False)())
    if not available:
        raise SB3ModelError(
            f"policy {spec}: --policy-arg device={device}, but this machine has no {kind} device "
            "(a CPU-only PyTorch build, or no GPU); use device=cpu"
        )
    count = getattr(backend, "device_count", None)
    if chosen.index is not None and kind != "cpu" and count is not None and chosen.index >= count():
        raise SB3ModelError(
            f"policy {spec}: --policy-arg device={device}, but this machine has {count()} {kind} device(s)"
        )


def _check(path: Path, model: Any, record: dict[str, Any], preset: Any, asked: dict[str, Any]) -> list[str]:
    """Refuses hard mismatches (both sides named); returns the allowable ones (dt, walls it cannot see)."""
    from socialnav.envs.config import observation_and_action_spaces
    from socialnav.policies.learned_loading import walled_scenarios

    world = preset.world
    where = f"preset {preset.name!r}"
    settings = dataclasses.asdict(ObservationSettings.from_dict(record["observation"]))
    for key, value in asked.items():
        if key in settings and (tuple(value) if key == "parts" else value) != settings[key]:
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
    if not same_space(model.action_space, expected_actions):
        raise SB3ModelError(
            f"{path}: action space {show_space(model.action_space)} of the model, "
            f"{show_space(expected_actions)} for {record['action_set']} {world.kinematics} actions at v_pref "
            f"{preset.robot.v_pref} under {where}"
        )
    transform = ObservationTransform(
        ObservationSettings(**settings), settings["max_humans"], world.kinematics, record["action_set"],
        sensing=recorded_sensing(record),
    )
    expected_obs = transform.single_space()
    if not same_space(model.observation_space, expected_obs):
        raise SB3ModelError(
            f"{path}: observation space {show_space(model.observation_space)} of the model, "
            f"{show_space(expected_obs)} from its recorded observation setting {settings}"
        )
    try:  # the lidar it reads, which it brings to a world without one (the evaluation's rule)
        world.with_sensors(model_sensors(ObservationSettings(**settings), recorded_sensing(record)))
    except ValueError as err:
        raise SB3ModelError(f"{path} under {where}: {err} (the model file's); evaluate it under a preset "
                            "without a lidar, to which it brings its own, or with the same lidar") from None
    mismatch = []
    if not math.isclose(float(record["dt"]), world.dt, rel_tol=1e-9):
        mismatch.append(f"dt {record['dt']!r} in the model file, {world.dt!r} in {where}")
    walled = walled_scenarios((*preset.evaluation.multi_human, *preset.evaluation.single_human))
    if walled and not transform.composition.shows_walls:
        # as for the project's checkpoints trained without walls: the model's input has no obstacles
        mismatch.append(
            f"walls: the model's observation has no obstacle points (obstacle_points = 0) nor a lidar, "
            f"{where} evaluates scenarios with walls ({', '.join(walled)}) that it cannot see"
        )
    return mismatch


