"""One registration record per learned policy: the single place that names a learned policy.

Everything else reads these records: the policy registry and ``socialnav list`` (description,
evaluation parameters; :mod:`socialnav.policies.learned_loading` makes each record a registry entry),
``socialnav train`` (which trainer, the policy's training defaults), checkpoint saving and loading (the
network factory, aliases; :mod:`socialnav.policies.learned.networks`), result tables (display label,
paper row: :func:`default_label`, :func:`default_paper_row`) and the table in docs/policies_learned.md
(:func:`markdown_table`, checked by a test). Adding a learned policy is one :class:`LearnedPolicySpec`
appended to :data:`BUILTIN` (or, from outside the package, :func:`register_learned_policy`).

This module is plain data: importing it imports neither torch nor the networks (``network`` names
its factory as ``module:attribute``, imported when a network is built).
"""

from __future__ import annotations

import dataclasses
import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from socialnav.sim.parts.base import NETWORK_PARTS

#: What a value-based policy's lookahead may assume of the humans' next states (no PyTorch needed to
#: check it: a preset's settings are checked where PyTorch may be missing).
VALUE_INFORMATION: tuple[str, ...] = ("constant_velocity", "oracle", "learned")

__all__ = [
    "TRAINERS",
    "CHECKPOINT_KINDS",
    "VALUE_DEFAULTS",
    "LearnedPolicySpec",
    "BUILTIN",
    "register_learned_policy",
    "learned_policy_specs",
    "learned_policy_names",
    "get_learned_spec",
    "canonical_name",
    "default_label",
    "default_paper_row",
    "markdown_table",
]

#: The trainers that ship, and the checkpoint kind each writes: ``value`` (imitation from ORCA, then
#: value-based RL with a one-step or model-predictive lookahead; train/value/) and ``ppo`` (an
#: actor-critic trained with PPO; train/ppo/). A record may name any trainer registered with
#: ``socialnav.train.register_trainer``; training refuses one that is not registered.
TRAINERS: Mapping[str, str] = MappingProxyType({"value": "value_policy", "ppo": "ppo_policy"})
#: How a checkpoint acts once loaded, by the record its config holds: ``value_policy`` (a value network
#: scoring candidate actions through the lookahead, a LearnedPolicy) or ``ppo_policy`` (an actor-critic
#: acting with its mean action, a RecurrentActorPolicy).
CHECKPOINT_KINDS = ("value_policy", "ppo_policy")
#: How docs and tables name the built-in trainers (another trainer is named by its name).
_TRAINER_LABELS = {"value": "value-based", "ppo": "PPO"}

#: The lookahead a value-based policy gets unless its record says otherwise: constant-velocity
#: prediction, one step deep and wide, CrowdNav's end-of-step reward estimate.
VALUE_DEFAULTS: Mapping[str, Any] = MappingProxyType(
    {"information": "constant_velocity", "planning_depth": 1, "planning_width": 1, "reward_rule": "end"}
)


@dataclass(frozen=True)
class LearnedPolicySpec:
    """The facts about one learned policy.

    Attributes:
        name: registry name, stored in checkpoints (``--policy NAME``).
        network: the network's factory (a class or a function building an ``nn.Module``), or its
            ``"module.path:attribute"`` so that reading the record does not import torch.
        description: one line shown by ``socialnav list``.
        label: display name in result tables and reports.
        trainer: the name of the trainer that trains it: ``value`` or ``ppo`` (:data:`TRAINERS`), or one
            registered with ``socialnav.train.register_trainer``.
        observes: what the network is fed, one phrase (docs table).
        paper: the publication it implements (docs table).
        paper_row: its row in Wang et al. 2022's tables, if it has one.
        aliases: other names of the same network and their ``socialnav list`` descriptions; a
            checkpoint always stores :attr:`name`.
        checkpoint_kind: how its checkpoints load (:data:`CHECKPOINT_KINDS`); "" takes the built-in
            trainer's (value: ``value_policy``, ppo: ``ppo_policy``); a record naming another trainer
            gives it, and it must be what that trainer writes.
        defaults: value_policy checkpoints only: overrides of :data:`VALUE_DEFAULTS` (information,
            planning_depth,
            planning_width, reward_rule), used for training and as evaluation parameters.
        required_information: value_policy checkpoints only: the one information setting the policy can be
            trained with (mp_rgl plans with the predictor it trains, so it needs ``learned``).
        one_human_training: trained with one human per episode when the training setting
            ``cadrl_one_human`` is on (CADRL's authors' setting).
        observation_parts: what it observes, by name: the observation parts its network's input
            builder composes (:mod:`socialnav.sim.parts`), ``robot`` (the state the lookahead
            propagates) then the sets of agents the network reads like humans, in order (default
            ``robot``, ``humans``, ``obstacle_points``).
        network_kwargs: required by the ``ppo`` trainer, refused with value_policy checkpoints (their
            networks take no arguments): ``network_kwargs(settings, n_humans)``, the network
            constructor's keyword arguments from the run's settings (``socialnav.train.PPOSettings``)
            and the training mix's human slots; to train among walls it also takes
            ``obstacle_slots=K``, the obstacle points that follow the human slots (docs/ppo.md).
    """

    name: str
    network: str | Callable[..., Any]
    description: str
    label: str
    trainer: str
    observes: str
    paper: str
    paper_row: str | None = None
    aliases: Mapping[str, str] = field(default_factory=dict)
    defaults: Mapping[str, Any] = field(default_factory=dict)
    required_information: str | None = None
    one_human_training: bool = False
    observation_parts: tuple[str, ...] = NETWORK_PARTS
    network_kwargs: Callable[..., dict[str, Any]] | None = None
    checkpoint_kind: str = ""

    def __post_init__(self) -> None:
        parts = self.observation_parts
        if not (isinstance(parts, tuple) and all(isinstance(p, str) for p in parts) and "robot" in parts):
            raise ValueError(f"learned policy {self.name!r}: observation_parts must be a tuple of "
                             f"observation part names holding 'robot', got {parts!r}")
        if not isinstance(self.trainer, str) or not self.trainer:
            raise ValueError(f"learned policy {self.name!r}: trainer must name a trainer, got "
                             f"{self.trainer!r}")
        if self.checkpoint_kind not in ("", *CHECKPOINT_KINDS):
            raise ValueError(f"learned policy {self.name!r}: checkpoint_kind {self.checkpoint_kind!r} must "
                             f"be one of {CHECKPOINT_KINDS}")
        if not self.checkpoint_kind and self.trainer not in TRAINERS:
            raise ValueError(f"learned policy {self.name!r}: trainer {self.trainer!r} is not a built-in "
                             f"trainer ({', '.join(TRAINERS)}): give checkpoint_kind, one of "
                             f"{CHECKPOINT_KINDS}")
        unknown = sorted(set(self.defaults) - set(VALUE_DEFAULTS))
        if unknown:
            raise ValueError(
                f"learned policy {self.name!r}: unknown default(s) {unknown}; valid: {sorted(VALUE_DEFAULTS)}"
            )
        needed = self.required_information
        if needed is not None and self.value_defaults["information"] != needed:
            raise ValueError(
                f"learned policy {self.name!r}: required_information {needed!r} must also be its default "
                f"information (defaults: information {self.value_defaults['information']!r})"
            )
        if self.kind != "value_policy" and (self.defaults or self.required_information):
            raise ValueError(
                f"learned policy {self.name!r}: lookahead defaults apply to value-based policies only"
            )
        if (self.trainer == "ppo" and self.network_kwargs is None) or (
                self.kind == "value_policy" and self.network_kwargs is not None):
            raise ValueError(
                f"learned policy {self.name!r}: network_kwargs is required for PPO policies and "
                f"refused for value networks (trainer {self.trainer!r})"
            )

    @property
    def kind(self) -> str:
        """How its checkpoints load: ``value_policy`` or ``ppo_policy`` (:data:`CHECKPOINT_KINDS`)."""
        return self.checkpoint_kind or TRAINERS[self.trainer]

    @property
    def value_defaults(self) -> dict[str, Any]:
        """The lookahead settings it trains and evaluates with unless told otherwise (value-based)."""
        return {**VALUE_DEFAULTS, **self.defaults}

    def evaluation_parameters(self) -> dict[str, Any]:
        """The parameters ``socialnav evaluate --policy NAME`` accepts, with their defaults."""
        if self.kind == "ppo_policy":
            return {"device": "cpu", "deterministic": True}
        d = self.value_defaults
        return {
            "information": d["information"],
            "device": "cpu",
            "planning_depth": d["planning_depth"],
            "planning_width": d["planning_width"],
            "scorer": "auto",
        }

    def network_factory(self) -> Callable[..., Any]:
        """The network's factory, imported now if the record names it by path (imports torch)."""
        if not isinstance(self.network, str):
            return self.network
        module, _, attr = self.network.partition(":")
        return getattr(importlib.import_module(module), attr)


def attn_graph_kwargs(settings: Any, n_humans: int, obstacle_slots: int = 0) -> dict[str, Any]:
    """crowdnav_pp's network arguments: every size of ``settings.network`` and ``normalize_obs``.

    Args:
        settings: the run's PPO settings.
        n_humans: the training mix's human slots (the attention takes any number).
        obstacle_slots: the obstacle encoding's point slots (the attention reads them as agents).

    Returns:
        The AttnGraphNet keyword arguments.
    """
    return dict(normalize_obs=settings.normalize_obs, **dataclasses.asdict(settings.network))


def mlp_actor_critic_kwargs(settings: Any, n_humans: int, obstacle_slots: int = 0) -> dict[str, Any]:
    """ppo_mlp's network arguments: prediction steps and initial σ, ``mlp_hidden``, human slots.

    The prediction steps and initial σ are shared with crowdnav_pp's ``network`` settings; the MLP's
    input has a slot per human of the training mix, and among walls one per obstacle point.

    Args:
        settings: the run's PPO settings.
        n_humans: the training mix's human slots.
        obstacle_slots: the obstacle encoding's point slots (0: no walls in the mix).

    Returns:
        The MLPActorCritic keyword arguments.
    """
    n = settings.network
    return dict(
        prediction_steps=n.prediction_steps,
        max_humans=n_humans,
        hidden=settings.mlp_hidden,
        normalize_obs=settings.normalize_obs,
        log_std_init=n.log_std_init,
        **({"obstacle_slots": obstacle_slots} if obstacle_slots else {}),
    )


def lidar_net_kwargs(settings: Any, n_humans: int, obstacle_slots: int = 0) -> dict[str, Any]:
    """lidar_ppo's network arguments: its lidar, the scans it reads each step, and MLP width.

    ``lidar_beams`` and ``lidar_range`` size its lidar, ``lidar_history`` the scans it reads,
    ``lidar_route_goal`` whether its goal is its route's.

    The network perceives walls and people through its lidar alone, so ``n_humans`` and the obstacle
    encoding's ``obstacle_slots`` size nothing of it.

    Args:
        settings: the run's PPO settings.
        n_humans: the training mix's human slots (not read).
        obstacle_slots: the obstacle encoding's point slots (not read).

    Returns:
        The LidarActorCritic keyword arguments.
    """
    return dict(lidar_beams=settings.lidar_beams, lidar_range=settings.lidar_range,
                lidar_history=settings.lidar_history, route_goal=settings.lidar_route_goal,
                hidden=settings.mlp_hidden, normalize_obs=settings.normalize_obs,
                log_std_init=settings.network.log_std_init)


_NETS = "socialnav.policies.learned"
_CROWDNAV_2019 = (
    "Chen, Liu, Kreiss, Alahi, \"Crowd-Robot Interaction: Crowd-aware Robot Navigation with "
    "Attention-based Deep Reinforcement Learning\", ICRA 2019"
)
_RGL_2020 = "Chen, Hu, Nikdel, Mori, Savva, \"Relational Graph Learning for Crowd Navigation\", IROS 2020"
_JOINT = "robot state + each human's 13-value agent-centric joint state"

#: The learned policies that ship, in the order of the docs table.
BUILTIN: tuple[LearnedPolicySpec, ...] = (
    LearnedPolicySpec(
        name="cadrl",
        network=f"{_NETS}.cadrl:CADRL",
        description="CADRL value network (Chen et al., ICRA 2017), one-step lookahead",
        label="CADRL",
        paper_row="CADRL",
        trainer="value",
        observes=_JOINT + ", pairwise (min over humans)",
        paper="Chen, Liu, Everett, How, \"Decentralized Non-communicating Multiagent Collision "
        "Avoidance with Deep Reinforcement Learning\", ICRA 2017",
        one_human_training=True,
    ),
    LearnedPolicySpec(
        name="lstm_rl",
        network=f"{_NETS}.lstm_rl:LSTMRL",
        description="LSTM value network in the spirit of GA3C-CADRL (Everett et al., IROS 2018), value-based",
        label="GA3C-CADRL (LSTM-RL)",
        paper_row="GA3C-CADRL",
        trainer="value",
        observes=_JOINT + ", LSTM over humans sorted by distance",
        paper="Everett, Chen, How, \"Motion Planning Among Dynamic, Decision-Making Agents with Deep "
        "Reinforcement Learning\", IROS 2018",
        aliases={
            "ga3c_cadrl": "alias of lstm_rl: an LSTM value network, not the A3C policy-gradient original"
        },
    ),
    LearnedPolicySpec(
        name="sarl",
        network=f"{_NETS}.sarl:SARL",
        description="SARL: attention over humans (Chen et al., ICRA 2019), one-step lookahead",
        label="SARL",
        trainer="value",
        observes=_JOINT + ", attention over humans",
        paper=_CROWDNAV_2019,
    ),
    LearnedPolicySpec(
        name="om_sarl",
        network=f"{_NETS}.sarl:om_sarl",
        description="OM-SARL: SARL with local occupancy maps (Chen et al., ICRA 2019)",
        label="OM-SARL",
        paper_row="OM-SARL",
        trainer="value",
        observes=_JOINT + " + a 4×4×3 local occupancy map around each human",
        paper=_CROWDNAV_2019,
    ),
    LearnedPolicySpec(
        name="rgl",
        network=f"{_NETS}.rgl:RGL",
        description="RGL: relational graph value network (Chen et al., IROS 2020), one-step lookahead",
        label="RGL",
        paper_row="RGL",
        trainer="value",
        observes=_JOINT + ", relational graph (relation matrix + 2 graph convolutions)",
        paper=_RGL_2020,
    ),
    LearnedPolicySpec(
        name="mp_rgl",
        network=f"{_NETS}.rgl:mp_rgl",
        description="model-predictive RGL: learned state predictor, d-step w-wide planning "
        "(Chen et al., 2020)",
        label="MP-RGL",
        trainer="value",
        observes=_JOINT + ", RGL's graph; humans' next states from a learned state predictor",
        paper=_RGL_2020,
        defaults={"information": "learned", "planning_depth": 2, "planning_width": 2, "reward_rule": "swept"},
        required_information="learned",
    ),
    LearnedPolicySpec(
        name="crowdnav_pp",
        network=f"{_NETS}.attn_graph:AttnGraphNet",
        description="CrowdNav++ attention graph (Liu et al., ICRA 2023): robot-human and human-human "
        "attention, GRU over time, continuous actions, trained with PPO; constant-velocity prediction",
        label="CrowdNav++ (attention graph, PPO)",
        trainer="ppo",
        observes="robot state + humans' positions and velocities with constant-velocity predictions",
        paper="Liu et al., \"Intention Aware Robot Crowd Navigation "
        "with Attention-Based Interaction Graph\", ICRA 2023",
        network_kwargs=attn_graph_kwargs,
    ),
    LearnedPolicySpec(
        name="ppo_mlp",
        network=f"{_NETS}.ppo_mlp:MLPActorCritic",
        description="plain MLP actor-critic over the robot and the nearest humans, continuous actions, "
        "trained with PPO (the reference for crowdnav_pp)",
        label="MLP (PPO)",
        trainer="ppo",
        observes="robot state + the nearest humans' positions and velocities (constant-velocity predictions)",
        paper="none (a baseline for crowdnav_pp)",
        network_kwargs=mlp_actor_critic_kwargs,
    ),
    LearnedPolicySpec(
        name="lidar_ppo",
        network=f"{_NETS}.lidar_net:LidarActorCritic",
        description="lidar actor-critic: the robot's state and goal and its 2-D lidar scan (circular 1-D "
        "convolutions), continuous actions, trained with PPO; brings its lidar to the world it acts in",
        label="Lidar (PPO)",
        trainer="ppo",
        observes="robot state + a 2-D lidar scan (no detections, no map; docs/perception.md)",
        paper="in the manner of DRL-VO (Xie & Dames, T-RO 2023) and robot_sf's lidar policies",
        network_kwargs=lidar_net_kwargs,
    ),
)

_SPECS: dict[str, LearnedPolicySpec] = {}
_ALIASES: dict[str, str] = {}


def register_learned_policy(spec: LearnedPolicySpec) -> LearnedPolicySpec:
    """Adds a learned policy; from then on the CLI, training, loading and ``socialnav list`` know it.

    Raises:
        ValueError: its name or one of its aliases is already taken.
    """
    for name in (spec.name, *spec.aliases):
        if name in _SPECS or name in _ALIASES:
            raise ValueError(f"learned policy {name!r} is already registered")
    _SPECS[spec.name] = spec
    _ALIASES.update({alias: spec.name for alias in spec.aliases})
    return spec


for _spec in BUILTIN:
    register_learned_policy(_spec)


def learned_policy_specs(trainer: str | None = None) -> list[LearnedPolicySpec]:
    """The registered records in registration order, all or those of one ``trainer``."""
    return [s for s in _SPECS.values() if trainer is None or s.trainer == trainer]


def learned_policy_names(trainer: str | None = None, aliases: bool = True) -> list[str]:
    """Every name ``--policy`` accepts for a learned policy (aliases after their policy)."""
    out = []
    for spec in learned_policy_specs(trainer):
        out += [spec.name, *(spec.aliases if aliases else ())]
    return out


def canonical_name(name: str) -> str:
    """The name a checkpoint stores (``ga3c_cadrl`` → ``lstm_rl``; other names unchanged)."""
    return _ALIASES.get(name, name)


def get_learned_spec(name: str) -> LearnedPolicySpec:
    """The record of a learned policy by name or alias.

    Raises:
        KeyError: not a learned policy (the message lists the known ones).
    """
    try:
        return _SPECS[canonical_name(name)]
    except KeyError:
        raise KeyError(
            f"unknown learned policy {name!r}; known: {', '.join(sorted(learned_policy_names()))}"
        ) from None


def default_label(policy: str) -> str:
    """The display name of a policy in tables: its record's label for a learned one, else its name."""
    try:
        return get_learned_spec(policy).label
    except KeyError:
        return policy


def default_paper_row(policy: str) -> str | None:
    """The row of Wang et al. 2022's tables a learned policy fills, if any (its record says)."""
    try:
        return get_learned_spec(policy).paper_row
    except KeyError:
        return None


def markdown_table() -> str:
    """The table of learned policies in docs/policies_learned.md (a test keeps the two equal)."""
    lines = ["| name (registry) | trainer | observes | paper |", "|---|---|---|---|"]
    for spec in learned_policy_specs():
        names = " = ".join(f"`{n}`" for n in (spec.name, *spec.aliases))
        trainer = _TRAINER_LABELS.get(spec.trainer, spec.trainer)
        lines.append(f"| {names} | {trainer} | {spec.observes} | {spec.paper} |")
    return "\n".join(lines)
