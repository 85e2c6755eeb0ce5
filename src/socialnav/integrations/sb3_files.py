"""Reading a saved Stable-Baselines3 model file without unpickling anything (the ``sb3:PATH`` policies).

SB3's own ``load`` unpickles (cloudpickle) every field of the zip's ``data`` JSON marked ``:serialized:``,
and unpickling can run anything. So every such field is rebuilt here from socialnav's own knowledge and
handed to SB3 as ``custom_objects``, which SB3 takes instead of unpickling the field: the spaces from the
socialnav record (or, without one, the raw env's under the preset), the policy class from the algorithm's
own policy aliases, ``policy_kwargs`` from known torch and SB3 classes, and what only training needs
(schedules, buffers, last observations) by constants. The readable parts SB3 writes beside each pickled
field only select among and check these candidates. docs/security.md lists what socialnav loads and how.
"""

from __future__ import annotations

import importlib
import io
import json
import re
import zipfile
from pathlib import Path
from typing import Any, TypeGuard

import numpy as np

from socialnav.envs.learner_wrappers import RECORD_FORMAT
from socialnav.integrations.sb3_pickles import foreign_object
from socialnav.sim.learner_obs import ObservationSettings, ObservationTransform

__all__ = [
    "ALGORITHM_MODULES",
    "SB3ModelError",
    "algorithm_class",
    "infer_record",
    "load_model",
    "read_saved_data",
    "record_spaces",
    "safe_custom_objects",
    "same_space",
    "saved_record",
    "show_space",
]

ALGORITHM_MODULES = ("stable_baselines3", "sb3_contrib")


class SB3ModelError(ValueError):
    """A model file that cannot be evaluated as asked (the message names the file and both sides)."""


def read_saved_data(path: Path, data: bytes) -> dict[str, Any]:
    """The zip's ``data`` JSON, read as JSON only (nothing in it is unpickled here)."""
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            saved = json.loads(archive.read("data").decode())
    except (zipfile.BadZipFile, KeyError, ValueError, UnicodeDecodeError) as err:
        raise SB3ModelError(f"{path} is not a Stable-Baselines3 model zip ({err})") from None
    if not isinstance(saved, dict):
        raise SB3ModelError(
            f"{path} is not a Stable-Baselines3 model zip (its data holds a {type(saved).__name__}, "
            "not an object)"
        )
    for key, value in saved.items():
        if _serialized(value):
            _refuse_foreign_objects(path, key, value[":serialized:"])
    return saved


def _refuse_foreign_objects(path: Path, key: str, encoded: Any) -> None:
    """Refuses a pickled field that names an object no Stable-Baselines3 model holds (``sb3_pickles``)."""
    try:
        foreign = foreign_object(encoded)
    except ValueError as err:
        raise SB3ModelError(f"{path}: field {key} of the model file is {err}") from None
    if foreign is not None:
        raise SB3ModelError(
            f"{path}: field {key} of the model file names {foreign}, which no Stable-Baselines3 model holds; "
            "socialnav refuses the file without unpickling it (docs/security.md)"
        )


#: Fields of the record :func:`socialnav.integrations.sb3.save_model` writes that loading reads.
_RECORD_FIELDS: dict[str, type | tuple[type, ...]] = {
    "observation": dict,
    "action_set": str,
    "kinematics": str,
    "rotation_limit": (int, float),
    "robot_v_pref": (int, float),
    "dt": (int, float),
}


def saved_record(path: Path, saved: dict[str, Any]) -> dict[str, Any] | None:
    """The model's socialnav record (None: saved without one), its fields checked."""
    if "socialnav_record" not in saved or saved["socialnav_record"] is None:
        return None
    record = saved["socialnav_record"]
    save_again = "save it again with socialnav.integrations.sb3.save_model"
    if not isinstance(record, dict):
        raise SB3ModelError(
            f"{path}: field socialnav_record of the model file is a {type(record).__name__} "
            f"({str(record)[:80]!r}), not the record socialnav writes; {save_again}"
        )
    if record.get("format") != RECORD_FORMAT:
        raise SB3ModelError(
            f"{path}: socialnav record of an unknown format ({str(record)[:80]}); {save_again}"
        )
    for key, kind in _RECORD_FIELDS.items():
        value = record.get(key)
        if not isinstance(value, kind) or isinstance(value, bool):
            raise SB3ModelError(
                f"{path}: field socialnav_record.{key} of the model file is {str(value)[:80]!r}; {save_again}"
            )
    if record["action_set"] not in ("continuous", "discrete"):
        raise SB3ModelError(f"{path}: field socialnav_record.action_set of the model file is "
                            f"{record['action_set'][:40]!r}, not 'continuous' or 'discrete'; {save_again}")
    if "algorithm" in record and not isinstance(record["algorithm"], str):
        raise SB3ModelError(f"{path}: field socialnav_record.algorithm of the model file is "
                            f"{str(record['algorithm'])[:80]!r}, not an algorithm's name; {save_again}")
    try:
        ObservationSettings.from_dict(record["observation"])
    except (ValueError, TypeError) as err:
        raise SB3ModelError(f"{path}: field socialnav_record.observation of the model file: {err}") from None
    return record


def algorithm_class(path: Path, asked: str | None, recorded: str | None) -> type:
    """The SB3 algorithm class named on the command line (``asked``) or in the file (``recorded``).

    Raises:
        SB3ModelError: The two differ, neither names one, or no installed algorithm has the name.
    """
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


# -- loading without unpickling -------------------------------------------------------------------
#
# SB3's ``BaseAlgorithm.load`` unpickles every field of the ``data`` JSON written as
# ``{":type:": ..., ":serialized:": <base64 cloudpickle>, <readable first-level attributes>}``, except
# the fields given in ``custom_objects``. Every pickled field is rebuilt below; the readable attributes SB3
# writes beside it (``str()`` of what is not JSON) only pick among socialnav's candidates and check them.


def _serialized(value: Any) -> TypeGuard[dict[str, Any]]:
    return isinstance(value, dict) and ":serialized:" in value


def _readable(items: Any) -> dict[str, Any]:
    """What SB3's ``data_to_json`` writes beside a pickled object: JSON-ready attributes, others' str()."""
    out = {}
    for key, value in dict(items).items():
        try:
            out[key] = json.loads(json.dumps(value))
        except (TypeError, ValueError):
            out[key] = str(value)
    return out


#: The readable attributes that identify a space of each kind (``_np_random`` and the like are state).
_SPACE_FIELDS = {
    "Box": ("dtype", "_shape", "low", "high", "bounded_below", "bounded_above"),
    "Discrete": ("n", "start"),
    "MultiBinary": ("n", "_shape"),
    "Dict": ("spaces",),
}


def _declares(declared: Any, space: Any) -> bool:
    """Whether the file's pickled space field describes exactly ``space`` (read from its readable parts)."""
    fields = _SPACE_FIELDS.get(type(space).__name__)
    if not fields or not _serialized(declared) or declared.get(":type:") != str(type(space)):
        return False
    mine = _readable(vars(space))

    def norm(value: Any) -> Any:
        return " ".join(value.split()) if isinstance(value, str) else value

    return all(norm(declared.get(key)) == norm(mine.get(key)) for key in fields)


def _show_declared(declared: Any) -> str:
    """A space field of the model file as its readable parts describe it."""
    if not _serialized(declared):
        return repr(declared)[:80]
    kind = str(declared.get(":type:", "?")).rsplit(".", 1)[-1].rstrip("'>")
    if kind == "Dict":
        return " ".join(str(declared.get("spaces", "{?}")).split())[:300]
    if kind == "Box":
        shape = tuple(declared["_shape"]) if isinstance(declared.get("_shape"), list) else "?"
        low, high, dtype = declared.get("low"), declared.get("high"), declared.get("dtype")
        return f"Box(low {low}, high {high}, {shape}, {dtype})"
    return f"{kind}({declared.get('n', '')})"


def recorded_sensing(record: dict[str, Any]) -> Any:
    """The sensing settings a model's record holds (its lidar's beams and range), None: the defaults.

    Raises:
        ConfigError: A recorded sensing field is unknown or out of range (named).
    """
    from socialnav.settings import from_dict
    from socialnav.sim.settings import SensingSettings

    given = record.get("sensing")
    return None if not given else from_dict(SensingSettings, given, "sensing")


def record_spaces(path: Path, saved: dict[str, Any], record: dict[str, Any]) -> tuple[Any, Any]:
    """The observation and action spaces the record describes, checked against the file's declared ones."""
    from socialnav.envs.config import observation_and_action_spaces
    from socialnav.sim.settings import WorldSettings

    settings = ObservationSettings.from_dict(record["observation"])
    try:
        transform = ObservationTransform(
            settings, int(record["observation"]["max_humans"]), record["kinematics"], record["action_set"],
            sensing=recorded_sensing(record),
        )
        # the two world settings an action space depends on, as the record stores them
        world = WorldSettings(kinematics=record["kinematics"], rotation_limit=float(record["rotation_limit"]))
    except (ValueError, TypeError, KeyError) as err:
        raise SB3ModelError(f"{path}: the socialnav record of the model file is not usable: {err}") from None
    observation_space = transform.single_space()
    v_pref = float(record["robot_v_pref"])
    _, action_space = observation_and_action_spaces(1, world, v_pref, record["action_set"])
    for key, space in (("observation_space", observation_space), ("action_space", action_space)):
        if not _declares(saved.get(key), space):
            raise SB3ModelError(
                f"{path}: field {key} of the model file, {_show_declared(saved.get(key))}, is not the "
                f"{show_space(space)} its socialnav record describes; save it again with "
                "socialnav.integrations.sb3.save_model"
            )
    return observation_space, action_space


def infer_record(path: Path, saved: dict[str, Any], preset: Any) -> tuple[dict[str, Any], tuple[Any, Any]]:
    """The record and spaces of a model saved without a record, when its spaces are the raw env's.

    The raw env's spaces under ``preset`` are built for each human count the file's declared observation
    space names; the one it declares exactly is taken.
    """
    from socialnav.envs.config import observation_and_action_spaces

    world, v_pref = preset.world, float(preset.robot.v_pref)
    declared = saved.get("observation_space")
    text = str(declared.get("spaces", "")) if _serialized(declared) else ""
    observation_space = None
    for n in sorted({int(n) for n in re.findall(r"\d+", text) if len(n) < 6}):  # candidate human counts
        space = observation_and_action_spaces(n, world, v_pref, "continuous")[0]
        if _declares(declared, space):
            observation_space = space
            break
    if observation_space is None:
        humans = max(int(preset.evaluation.n_humans), 1)
        raw = observation_and_action_spaces(humans, world, v_pref, "continuous")[0]
        raise SB3ModelError(
            f"{path} carries no socialnav record and its observation space {_show_declared(declared)} is not "
            f"the raw env's (float64, world frame, SI units: {show_space(raw)} under preset "
            f"{preset.name!r}), "
            "so how it converted observations is unknown. A model trained on SocialNavVecEnv, whose "
            "default observation is the learner's (float32), must be saved with "
            "socialnav.integrations.sb3.save_model, which records the conversion"
        )
    declared_action = saved.get("action_space")
    discrete = _serialized(declared_action) and "Discrete" in str(declared_action.get(":type:"))
    action_set = "discrete" if discrete else "continuous"
    action_space = observation_and_action_spaces(1, world, v_pref, action_set)[1]
    if not _declares(declared_action, action_space):
        raise SB3ModelError(
            f"{path}: action space {_show_declared(declared_action)} of the model, "
            f"{show_space(action_space)} for {action_set} {world.kinematics} actions at v_pref "
            f"{preset.robot.v_pref} under preset {preset.name!r}"
        )
    humans = observation_space["humans"]
    record = {
        "format": RECORD_FORMAT,
        "observation": ObservationSettings(
            max_humans=int(humans.shape[0]), dtype=str(np.dtype(humans.dtype))
        ).to_dict(),
        "action_set": action_set,
        # not recorded: the action space check above stands for them
        "kinematics": world.kinematics,
        "rotation_limit": world.rotation_limit,
        "robot_v_pref": preset.robot.v_pref,
        "dt": world.dt,
    }
    return record, (observation_space, action_space)


_ADDRESS = re.compile(r" at 0x[0-9a-fA-F]+")


def _names_class(declared: Any, cls: type) -> bool:
    """Whether a pickled class field's readable parts (module, methods) are those of ``cls``."""
    if not _serialized(declared) or declared.get("__module__") != cls.__module__:
        return False
    own = _readable(vars(cls))
    methods = {k: v for k, v in declared.items() if isinstance(v, str) and v.startswith("<function ")}
    if not methods:
        return declared.get("__doc__") == cls.__doc__
    return all(_ADDRESS.sub("", v) == _ADDRESS.sub("", str(own.get(k))) for k, v in methods.items())


def _declared_class_name(declared: Any) -> str:
    if not _serialized(declared):
        return repr(declared)[:80]
    for value in declared.values():
        found = re.match(r"<function ([\w.]+)\.\w+ at ", value) if isinstance(value, str) else None
        if found:
            return f"{found.group(1)} of {declared.get('__module__')}"
    return f"a class of {str(declared.get('__module__'))[:80]}"


def _policy_class(path: Path, saved: dict[str, Any], algorithm: type) -> type:
    """The algorithm's own policy class the file names (one of its ``policy_aliases``)."""
    declared = saved.get("policy_class")
    aliases = getattr(algorithm, "policy_aliases", {})
    if isinstance(declared, str) and declared in aliases:
        return aliases[declared]
    for cls in aliases.values():
        if _names_class(declared, cls):
            return cls
    raise SB3ModelError(
        f"{path}: cannot be loaded as {algorithm.__name__} (its field policy_class, "
        f"{_declared_class_name(declared)}, is none of {algorithm.__name__}'s policies {', '.join(aliases)}; "
        "socialnav does not unpickle a custom policy class)"
    )


#: ``policy_kwargs`` entries that hold a class; each must be one socialnav knows (see _known_classes).
_CLASS_KWARGS = ("activation_fn", "optimizer_class", "features_extractor_class")


def _known_classes() -> dict[str, type]:
    """The classes a ``policy_kwargs`` entry may name, by the str() SB3 writes for them."""
    import torch
    from stable_baselines3.common import torch_layers
    from stable_baselines3.common.sb2_compat.rmsprop_tf_like import RMSpropTFLike

    nn, optim = torch.nn, torch.optim
    classes = [
        nn.ReLU, nn.Tanh, nn.ELU, nn.LeakyReLU, nn.SiLU, nn.GELU, nn.Sigmoid, nn.Softplus, nn.SELU,
        nn.CELU, nn.Mish, nn.Hardtanh, nn.Identity,
        optim.Adam, optim.AdamW, optim.RMSprop, optim.SGD, optim.Adamax, optim.NAdam, optim.RAdam,
        RMSpropTFLike,
        torch_layers.FlattenExtractor, torch_layers.CombinedExtractor, torch_layers.NatureCNN,
    ]
    return {str(cls): cls for cls in classes}


def _policy_kwargs(path: Path, declared: dict[str, Any]) -> dict[str, Any]:
    """A pickled ``policy_kwargs`` dict rebuilt from its readable entries (its classes from known ones)."""
    known = _known_classes()
    kwargs = {}
    for key, value in declared.items():
        if key.startswith(":"):
            continue
        if key in _CLASS_KWARGS and isinstance(value, str) and value in known:
            kwargs[key] = known[value]
        elif isinstance(value, str):
            # a class socialnav does not know, or an object SB3 could only write as its str()
            raise SB3ModelError(
                f"{path}: field policy_kwargs of the model file holds {key} = {value[:80]!r}, which "
                "socialnav cannot rebuild without unpickling it (known: torch activations and optimizers, "
                "SB3's feature extractors)"
            )
        else:
            kwargs[key] = value
    return kwargs


def _training_only() -> dict[str, Any]:
    """Constants for the pickled fields that only training reads (the loaded model only predicts).

    Schedules are rebuilt by ``_setup_model`` from the plain ``learning_rate`` and exploration
    settings anyway; buffers are chosen by ``_setup_model`` from the observation space when None.
    """
    from stable_baselines3.common.type_aliases import TrainFreq, TrainFrequencyUnit
    from stable_baselines3.common.utils import FloatSchedule

    return {
        "lr_schedule": FloatSchedule(0.0),
        "learning_rate": 0.0,  # pickled only where it was a schedule
        "clip_range": 0.2,  # SB3's default
        "clip_range_vf": None,
        "exploration_schedule": FloatSchedule(0.0),
        "train_freq": TrainFreq(1, TrainFrequencyUnit.STEP),
        "action_noise": None,
        "replay_buffer_class": None,
        "rollout_buffer_class": None,
        "_last_obs": None,
        "_last_original_obs": None,
        "_last_episode_starts": None,
        "ep_info_buffer": None,
        "ep_success_buffer": None,
    }


def safe_custom_objects(
    path: Path, saved: dict[str, Any], algorithm: type, observation_space: Any, action_space: Any
) -> dict[str, Any]:
    """What SB3's ``load`` takes instead of every pickled field of the file (``custom_objects``).

    Raises:
        SB3ModelError: A pickled field socialnav cannot rebuild (named), before anything is unpickled.
    """
    objects: dict[str, Any] = {
        "policy_class": _policy_class(path, saved, algorithm),
        "observation_space": observation_space,
        "action_space": action_space,
        "env": None,  # a saved env id would be gym.make'd, importing the module it names
    }
    constants = _training_only()
    for key, value in saved.items():
        if key in objects or not _serialized(value):
            continue
        if key == "policy_kwargs":
            objects[key] = _policy_kwargs(path, value)
        elif key in constants:
            objects[key] = constants[key]
        else:
            raise SB3ModelError(
                f"{path}: field {key} of the model file is a pickled {str(value.get(':type:'))[:80]}, which "
                "socialnav cannot rebuild; it never unpickles a model file (docs/security.md)"
            )
    return objects


def load_model(path: Path, algorithm: Any, data: bytes, objects: dict[str, Any], device: str) -> Any:
    """SB3's load of ``data`` with every pickled field replaced by ``objects`` (nothing is unpickled)."""
    unpickled = [k for k, v in read_saved_data(path, data).items() if _serialized(v) and k not in objects]
    if unpickled:  # the bytes are not the ones the objects were made for
        raise SB3ModelError(f"{path}: field(s) {', '.join(unpickled)} of the model file would be unpickled")
    try:
        return algorithm.load(io.BytesIO(data), device=device, custom_objects=objects)
    except Exception as err:  # SB3 raises many kinds; the user's fix is the same: file or algorithm
        raise SB3ModelError(
            f"{path}: cannot be loaded as {algorithm.__name__} ({type(err).__name__}: {err})"
        ) from None


def same_space(a: Any, b: Any) -> bool:
    """Whether two Gymnasium spaces are the same (kind, keys, shapes, dtypes, bounds)."""
    if type(a).__name__ != type(b).__name__:
        return False
    if hasattr(a, "spaces") and isinstance(a.spaces, dict):
        return set(a.spaces) == set(b.spaces) and all(same_space(a[k], b[k]) for k in a.spaces)
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


def show_space(space: Any) -> str:
    """A space in one line, as loading errors name it."""
    if hasattr(space, "spaces") and isinstance(space.spaces, dict):
        return "{" + ", ".join(f"{k}: {show_space(v)}" for k, v in sorted(space.spaces.items())) + "}"
    if type(space).__name__ == "Box":
        low, high = np.unique(space.low), np.unique(space.high)
        bounds = (
            f"[{low[0]:g}, {high[0]:g}]"
            if low.size == 1 and high.size == 1
            else f"[{np.array2string(space.low, precision=3)}, {np.array2string(space.high, precision=3)}]"
        )
        return f"Box{bounds} {space.shape} {np.dtype(space.dtype).name}"
    return str(space)
