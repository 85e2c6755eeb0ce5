"""A learned policy's checkpoint → the policy that acts with it; torch is imported only when one loads.

A learned policy is built from a checkpoint written by ``socialnav train``. Its record's checkpoint kind
(:mod:`socialnav.policies.learned_catalog`) says how: a ``value_policy`` checkpoint loads into a
:class:`LearnedPolicy` (:func:`load_learned_policy`; its config holds ``value_policy``: kinematics,
gamma, information, rotation_limit, dt and the reward constants, so that the evaluator scores candidate
actions exactly as the trainer did), a ``ppo_policy`` one into a
:class:`~socialnav.policies.learned.ppo_policy.RecurrentActorPolicy` (:func:`load_ppo_policy`). Both
refuse a checkpoint trained for another world than the preset (:func:`checked_preset_mismatches`).
:func:`register_catalog` makes every record a policy registry entry whose factory is its loader, the
factory ``build_policy`` (:mod:`socialnav.policies.building`) calls.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from socialnav.policies.learned_catalog import get_learned_spec, learned_policy_specs
from socialnav.policies.registry import is_registered, register_policy
from socialnav.sim.observation import Observation, check_observation
from socialnav.sim.settings import HEADED_KINEMATICS, DiffDriveSettings


class LearnedPolicy:
    """A trained value network acting greedily through one-step lookahead (batched).

    Args:
        name: Registered policy name.
        value_policy: The :class:`socialnav.policies.learned.ValuePolicy` to act with.
        checkpoint: Where the network came from (recorded with results).
    """

    def __init__(
        self,
        name: str,
        value_policy: Any,
        checkpoint: Path | None = None,
        preset_mismatch: list[str] | None = None,
    ):
        self.name = name
        self.value_policy = value_policy
        self.information = value_policy.information
        self.checkpoint = checkpoint
        self.preset_mismatch = list(preset_mismatch or [])  # allowed differences, recorded with results

    def act(self, observation: Observation) -> np.ndarray:
        """Actions of the value-based policy for B episodes (one-step lookahead over the action set).

        Args:
            observation: The world's observation of B episodes; ``oracle`` information needs ``next_humans``.

        Returns:
            (B, 2) float64 robot velocities [m/s].

        Raises:
            ValueError: An oracle policy was given an observation without the humans' next states.
        """
        if self.information == "oracle" and observation.next_humans is None:
            raise ValueError(
                f"policy {self.name!r} uses oracle information: observe the world with oracle=True"
            )
        check_observation(observation, self.name, self.value_policy.kinematics,
                          oracle=self.information == "oracle")
        actions = np.zeros((observation.batch_size, 2))
        rows = np.flatnonzero(observation.active)
        if rows.size == 0:
            return actions
        # Only episodes whose robot still acts are scored: parked robots (M_III continuation) and
        # idle slots would otherwise cost a full lookahead each.
        obs = observation if rows.size == observation.batch_size else observation.take(rows)
        _, chosen = self.value_policy.act(
            obs, next_humans=obs.next_humans if self.information == "oracle" else None
        )
        actions[rows] = np.asarray(chosen, dtype=np.float64)
        return actions

    def describe(self) -> dict[str, Any]:
        """The record stored with results: policy, information, checkpoint and lookahead parameters."""
        vp = self.value_policy
        return {
            "policy": self.name,
            "information": self.information,
            "checkpoint": None if self.checkpoint is None else str(self.checkpoint),
            "planning_depth": vp.planning_depth,
            "planning_width": vp.planning_width,
            "reward_rule": vp.reward_rule,
            # The evaluator in effect ("native" or "torch"): values differ by float32 rounding.
            "scorer": vp.active_scorer,
            # Recorded only (RECORDED_ONLY): the kernels' values are bit-identical.
            **({"native_kernel": vp.native_kernel} if vp.native_kernel else {}),
            **({"preset_mismatch_allowed": self.preset_mismatch} if self.preset_mismatch else {}),
        }


#: What the checkpoint's ``value_policy`` may hold (the ValuePolicy arguments the trainer records).
_VALUE_POLICY_KEYS = (
    "kinematics",
    "gamma",
    "information",
    "rotation_limit",
    "dt",
    "reward",
    "planning_depth",
    "planning_width",
    "reward_rule",
    "obstacle_encoding",
    "diff_drive",
)
_REWARD_KEYS = (
    "success_reward",
    "collision_penalty",
    "discomfort_dist",
    "discomfort_penalty_factor",
    "time_step",
)


class PresetMismatchError(ValueError):
    """A checkpoint trained for another world than the preset it is evaluated under."""


def walled_scenarios(names: Any) -> list[str]:
    """The names among ``names`` whose registered scenario has walls (unknown names are left out)."""
    from socialnav.scenarios.registry import UnknownScenarioError, get_scenario
    from socialnav.scenarios.walls import WalledScenario

    out = []
    for name in names or ():
        try:
            if issubclass(get_scenario(str(name)), WalledScenario):
                out.append(str(name))
        except UnknownScenarioError:
            continue
    return out


def _walls_mismatch(trained: Any, preset: Any) -> list[str]:
    """Refuse to evaluate a network trained without walls among walls.

    Its input has no obstacles, so it cannot see them; this is refused like any other world mismatch, naming
    both sides.
    """
    training = trained.get("training") if isinstance(trained, dict) else None
    if not isinstance(training, dict) or "scenarios" not in training:
        return []  # the checkpoint does not record what it was trained on
    evaluated = walled_scenarios((*preset.evaluation.multi_human, *preset.evaluation.single_human))
    if not evaluated or walled_scenarios(training["scenarios"]):
        return []
    return [
        f"walls: the checkpoint was trained without walls (on {', '.join(map(str, training['scenarios']))}), "
        f"preset {preset.name!r} evaluates scenarios with walls ({', '.join(evaluated)}) that its network "
        "cannot see"
    ]


def preset_mismatches(config: dict[str, Any], preset: Any) -> list[str]:
    """Where the world a checkpoint was trained for differs from ``preset``'s, one phrase each.

    Compared: dt, kinematics, the rotation limit and a differential drive's limits, the reward constants
    (the lookahead scores actions with them), the robot's v_pref (it scales the action set), and walls
    (a checkpoint trained without walls, evaluated on scenarios with walls). A difference makes the policy
    act on a model of the world that is not the one simulated.
    """
    # A value-based checkpoint records its world under value_policy, a PPO one under ppo_policy.
    vp = config.get("value_policy") or config.get("ppo_policy") or {}
    reward = vp.get("reward", {})
    world = preset.world
    pairs: list[tuple[str, Any, Any]] = [
        ("dt", vp.get("dt"), world.dt),
        ("kinematics", vp.get("kinematics"), world.kinematics),
    ]
    if set(HEADED_KINEMATICS) & {vp.get("kinematics"), world.kinematics}:
        pairs.append(("rotation_limit", vp.get("rotation_limit"), world.rotation_limit))
    if "diff_drive" in (vp.get("kinematics"), world.kinematics):
        # the limits a differential-drive policy learned to drive within (the trained preset's world)
        trained_world = (config.get("preset") or {}).get("world") or {}
        limits = trained_world.get("diff_drive") or {}
        for key, value in dataclasses.asdict(world.diff_drive).items():
            pairs.append((f"diff_drive.{key}", limits.get(key, getattr(DiffDriveSettings(), key)), value))
    for key in _REWARD_KEYS[:-1]:
        pairs.append((f"reward.{key}", reward.get(key), getattr(world.reward, key)))
    trained = config.get("preset", {})
    robot = trained.get("robot", {}) if isinstance(trained, dict) else {}
    if isinstance(robot, dict) and "v_pref" in robot:
        pairs.append(("robot.v_pref", robot["v_pref"], preset.robot.v_pref))
    out = _walls_mismatch(trained, preset)
    for name, ours, theirs in pairs:
        if ours is None:
            continue  # not recorded by this checkpoint: nothing to compare
        same = (
            math.isclose(float(ours), float(theirs), rel_tol=1e-9, abs_tol=1e-12)
            if isinstance(ours, int | float) and isinstance(theirs, int | float)
            else ours == theirs
        )
        if not same:
            out.append(f"{name} {ours!r} in the checkpoint, {theirs!r} in preset {preset.name!r}")
    return out


def perception_note(what: str, trained: Any, preset: Any) -> str | None:
    """A note where ``preset``'s robot detects the humans otherwise than the one ``what`` was trained with.

    Not a mismatch that refuses the policy: evaluating a policy under another perception than its training
    one (a full-observation policy under ``wang2022_partial``) is an experiment of its own. The lidar is not
    compared: a policy that reads one brings it (``WorldSettings.with_sensors``).

    Args:
        what: The policy's source, for the note ("checkpoint PATH").
        trained: The training world's ``sensing`` section as recorded (None or {}: the exact defaults).
        preset: The evaluation's preset.
    """
    from socialnav.settings import ConfigError, from_dict
    from socialnav.sim.settings import LIDAR_FIELDS, SensingSettings

    if preset is None or (trained is not None and not isinstance(trained, dict)):
        return None
    try:
        before = from_dict(SensingSettings, trained or {}, "sensing")
    except ConfigError:
        return None  # a record of another version: nothing to compare
    now = preset.world.sensing
    changed = [f"{f.name} {getattr(before, f.name)!r} -> {getattr(now, f.name)!r}"
               for f in dataclasses.fields(SensingSettings)
               if f.name not in LIDAR_FIELDS and getattr(before, f.name) != getattr(now, f.name)]
    if not changed:
        return None
    return (f"{what} was trained with other detections than preset {preset.name!r} gives "
            f"({', '.join(changed)}, training -> evaluation): it is evaluated with the preset's "
            "(docs/perception.md)")


def checked_preset_mismatches(
    checkpoint: Any, config: dict[str, Any], preset: Any, allow: bool
) -> list[str]:
    """The world differences of a checkpoint under ``preset``.

    A :class:`PresetMismatchError` names them unless ``allow`` (then the caller records them); a
    kinematics mismatch is refused even then, as for SB3 models.
    """
    if preset is not None and not (config.get("value_policy") or config.get("ppo_policy")):
        # e.g. saved by hand with save_checkpoint and a config of one's own: nothing to compare
        warnings.warn(
            f"checkpoint {checkpoint} records no training world (config.value_policy): its dt, kinematics, "
            f"reward and robot v_pref cannot be compared with preset {preset.name!r}, and are assumed to "
            "match (socialnav train records them)", UserWarning, stacklevel=3,
        )
    trained = config.get("preset")
    trained_world = trained.get("world") if isinstance(trained, dict) else None
    sensing = trained_world.get("sensing") if isinstance(trained_world, dict) else None
    note = perception_note(f"checkpoint {checkpoint}", sensing, preset)
    if note:
        warnings.warn(note, UserWarning, stacklevel=3)
    mismatch = preset_mismatches(config, preset) if preset is not None else []
    kinematics = [m for m in mismatch if m.startswith("kinematics ")]
    if kinematics:  # the network's actions would be read in another action space: never meaningful
        raise PresetMismatchError(
            f"checkpoint {checkpoint} was trained for another robot: {kinematics[0]}; its actions cannot be "
            "played by this robot (--allow-preset-mismatch does not cover kinematics): evaluate it under a "
            "preset with the same kinematics"
        )
    if mismatch and not allow:
        raise PresetMismatchError(
            f"checkpoint {checkpoint} was trained for another world: {'; '.join(mismatch)}; "
            "evaluate it under a matching preset, or pass --allow-preset-mismatch (recorded in the results)"
        )
    return mismatch


def load_learned_policy(
    name: str,
    checkpoint: str | Path,
    information: str | None = None,
    device: str = "cpu",
    planning_depth: int | None = None,
    planning_width: int | None = None,
    preset: Any = None,
    allow_preset_mismatch: bool = False,
    scorer: str = "auto",
) -> LearnedPolicy:
    """Loads ``checkpoint`` (refusing one of another policy or input size) into a LearnedPolicy.

    ``information``, ``planning_depth`` and ``planning_width`` override the checkpoint's settings
    (None keeps them); ``learned`` needs a checkpoint that stores a state predictor. ``scorer``: what
    evaluates the network (:class:`~socialnav.policies.learned.ValuePolicy`); "auto" takes the native
    SARL / OM-SARL evaluator where it applies.

    Raises:
        CheckpointError: The checkpoint is unreadable or its recorded settings are malformed.
        PresetMismatchError: It was trained for another world than ``preset`` (both values are named),
            unless ``allow_preset_mismatch``; the allowed differences are then recorded in ``describe()``.
    """
    from socialnav.policies.learned import ValuePolicy, load_checkpoint
    from socialnav.policies.learned.checkpoint import CheckpointError
    from socialnav.policies.learned.native_scoring import ScorerError
    from socialnav.policies.learned.state import RewardParams

    ckpt = load_checkpoint(checkpoint, name, map_location=device)
    settings = ckpt.config.get("value_policy", {})
    where = f"checkpoint {checkpoint}: config.value_policy"
    if not isinstance(settings, dict):
        raise CheckpointError(f"{where} must be a mapping, got {type(settings).__name__}")
    unknown = sorted(set(settings) - set(_VALUE_POLICY_KEYS))
    reward = settings.get("reward", {})
    if unknown:
        raise CheckpointError(f"{where} has unknown key(s) {', '.join(unknown)}")
    if not isinstance(reward, dict) or set(reward) - set(_REWARD_KEYS):
        raise CheckpointError(
            f"{where}.reward must be a mapping of {', '.join(_REWARD_KEYS)}, got {reward!r}"
        )
    mismatch = checked_preset_mismatches(checkpoint, ckpt.config, preset, allow_preset_mismatch)
    settings = dict(settings)
    settings.pop("reward", None)
    for key, value in (
        ("information", information),
        ("planning_depth", planning_depth),
        ("planning_width", planning_width),
    ):
        if value is not None:
            settings[key] = value
    if settings.get("information") == "learned" and ckpt.predictor is None:
        raise ValueError(
            f"checkpoint {checkpoint} stores no state predictor, so information 'learned' is not available "
            "(train with --information learned, or --policy mp_rgl)"
        )
    try:
        policy = ValuePolicy(
            ckpt.model,
            reward_params=RewardParams(**reward),
            device=device,
            predictor=ckpt.predictor,
            observation_parts=get_learned_spec(name).observation_parts,
            scorer=scorer,
            **settings,
        )
    except ScorerError as err:  # the caller's choice of scorer, not a fault of the checkpoint
        raise ScorerError(f"{name}: {err}") from None
    except (TypeError, ValueError) as err:
        if any(v is not None for v in (information, planning_depth, planning_width)):
            # settings the caller gave over the checkpoint's (e.g. oracle information for mp_rgl's depth
            # 2): the combination is the caller's, not a fault of the checkpoint
            raise ValueError(f"policy {name!r}: {err}") from None
        raise CheckpointError(f"{where} is invalid: {err}") from None
    return LearnedPolicy(name, policy, Path(checkpoint), mismatch)


def _factory(name: str):
    def make(
        checkpoint: Path,
        preset: Any = None,
        information: str | None = None,
        device: str = "cpu",
        planning_depth: int | None = None,
        planning_width: int | None = None,
        allow_preset_mismatch: bool = False,
        scorer: str = "auto",
        **_: Any,
    ) -> LearnedPolicy:
        return load_learned_policy(
            name,
            checkpoint,
            information,
            device,
            planning_depth,
            planning_width,
            preset,
            allow_preset_mismatch,
            scorer,
        )

    return make


#: What a PPO checkpoint's ``ppo_policy`` holds (the world the actor was trained for).
PPO_POLICY_KEYS = ("kinematics", "rotation_limit", "dt", "reward")
#: What it may hold besides: the obstacle encoding of a network trained among walls, a differential
#: drive's limits (its actions span its speeds, reversing included), a unicycle's action squash
#: (``span``; a unicycle record without it clipped: ``attn_graph.recorded_action_squash``).
PPO_POLICY_OPTIONAL_KEYS = ("obstacle_encoding", "diff_drive", "action_squash")


def _ppo_obstacle_encoding(settings: dict[str, Any], model: Any, where: str) -> Any:
    """The checkpoint's obstacle encoding (None when it records none), checked against its network.

    An MLP reads a fixed number of point slots (``obstacle_slots``), which must be the encoding's count.
    """
    from socialnav.policies.learned.checkpoint import CheckpointError
    from socialnav.settings import ConfigError
    from socialnav.sim.obstacle_points import ObstaclePoints

    raw = settings.get("obstacle_encoding")
    try:
        encoding = None if raw is None else ObstaclePoints.from_dict(raw)
    except ConfigError as err:
        raise CheckpointError(f"{where}.obstacle_encoding is invalid: {err}") from None
    slots = getattr(model, "obstacle_slots", None)
    count = 0 if encoding is None else encoding.count
    if slots is not None and slots != count:
        raise CheckpointError(
            f"{where}.obstacle_encoding has {count} point slots, its network reads {slots}"
        )
    return encoding


def load_ppo_policy(
    name: str,
    checkpoint: str | Path,
    device: str = "cpu",
    preset: Any = None,
    allow_preset_mismatch: bool = False,
    deterministic: bool = True,
):
    """Load a PPO checkpoint of ``name`` into a :class:`RecurrentActorPolicy`.

    It takes mean actions unless ``deterministic`` is False. A checkpoint trained among walls records
    its obstacle encoding (``config.ppo_policy.obstacle_encoding``), which the policy rebuilds; one
    without the key reads no obstacles.

    Raises:
        CheckpointError: unreadable, another policy, or malformed ``config.ppo_policy``.
        PresetMismatchError: trained for another world than ``preset`` (unless ``allow_preset_mismatch``).
    """
    from socialnav.policies.learned import load_checkpoint
    from socialnav.policies.learned.attn_graph import recorded_action_squash
    from socialnav.policies.learned.checkpoint import CheckpointError
    from socialnav.policies.learned.ppo_policy import RecurrentActorPolicy

    ckpt = load_checkpoint(checkpoint, name, expected_input_dim=-1, map_location=device)
    settings = ckpt.config.get("ppo_policy")
    where = f"checkpoint {checkpoint}: config.ppo_policy"
    if (
        not isinstance(settings, dict)
        or not set(PPO_POLICY_KEYS) <= set(settings)
        or set(settings) - set(PPO_POLICY_KEYS) - set(PPO_POLICY_OPTIONAL_KEYS)
    ):
        raise CheckpointError(
            f"{where} must be a mapping of {', '.join(PPO_POLICY_KEYS)} (and optionally "
            f"{', '.join(PPO_POLICY_OPTIONAL_KEYS)}; a checkpoint written by "
            f"`socialnav train --policy {name}`), got {settings!r}"
        )
    encoding = _ppo_obstacle_encoding(settings, ckpt.model, where)
    try:
        squash = recorded_action_squash(settings["kinematics"], settings)
    except ValueError as e:
        raise CheckpointError(f"{where}: {e}") from None
    mismatch = checked_preset_mismatches(checkpoint, ckpt.config, preset, allow_preset_mismatch)
    return RecurrentActorPolicy(
        name, ckpt.model, kinematics=settings["kinematics"], rotation_limit=settings["rotation_limit"],
        dt=settings["dt"], device=device, deterministic=deterministic, checkpoint=Path(checkpoint),
        preset_mismatch=mismatch, obstacle_encoding=encoding,
        observation_parts=get_learned_spec(name).observation_parts, diff_drive=settings.get("diff_drive"),
        action_squash=squash,
    )


def _ppo_factory(name: str):
    def make(
        checkpoint: Path,
        preset: Any = None,
        device: str = "cpu",
        deterministic: bool = True,
        allow_preset_mismatch: bool = False,
        **_: Any,
    ):
        return load_ppo_policy(name, checkpoint, device, preset, allow_preset_mismatch, deterministic)

    return make


def register_catalog() -> None:
    """Register every learned policy of the catalog not registered yet.

    Records added after the first call appear on the next one: those whose checkpoints hold a
    ``value_policy`` load into a :class:`LearnedPolicy`, those holding a ``ppo_policy`` into a
    :class:`~socialnav.policies.learned.ppo_policy.RecurrentActorPolicy`.
    """
    for spec in learned_policy_specs():
        factory = _ppo_factory if spec.kind == "ppo_policy" else _factory
        for name, description in ((spec.name, spec.description), *spec.aliases.items()):
            if not is_registered(name):
                register_policy(
                    name, description=description, learned=True, parameters=spec.evaluation_parameters()
                )(factory(name))
