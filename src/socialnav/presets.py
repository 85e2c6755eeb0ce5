"""Protocol presets: typed settings loaded from the YAML files shipped in ``socialnav/configs``.

A preset fixes the world's semantics, the robot, the evaluation protocol (which scenarios, how many
episodes, which visibility passes) and the training scenario mix. ``load_preset("wang2022")`` loads
a shipped one; a path to a YAML file loads a user's own.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

from socialnav.config import ConfigError, check, from_dict
from socialnav.sim.settings import VISIBILITIES, WorldSettings

MULTI_HUMAN = ("circle_crossing", "random", "parallel_traffic", "perpendicular_traffic")
SINGLE_HUMAN = ("passing", "overtaking", "crossing")
VISIBILITY_CHOICES = (*VISIBILITIES, "both")


@dataclass(frozen=True)
class RobotSettings:
    """The robot's body and speed.

    Attributes:
        v_pref: Preferred (and maximum) speed [m/s], in (0, 100].
        radius: Disc radius [m], in (0, 100].
    """
    v_pref: float = 1.0  # [m/s]
    radius: float = 0.3  # [m]

    def __post_init__(self) -> None:
        check(self.v_pref > 0, "robot.v_pref", self.v_pref, "must be > 0")
        check(self.radius > 0, "robot.radius", self.radius, "must be > 0")
        check(self.v_pref <= 100, "robot.v_pref", self.v_pref, "must be <= 100 m/s")
        check(self.radius <= 100, "robot.radius", self.radius, "must be <= 100 m")


@dataclass(frozen=True)
class EvaluationSettings:
    """How the protocol evaluates a policy.

    Attributes:
        split: The episode split evaluated (``test``, ``val`` or ``train``).
        multi_human: The multi-human scenarios.
        single_human: The single-human scenarios (one human; Table III's passing sides).
        n_humans: Humans per multi-human episode.
        episodes: Episodes per multi-human scenario.
        repeats: Episodes per single-human offset.
        visibility: ``visible``, ``invisible`` or ``both`` (the robot seen by the humans or not).
        continuation_cap: Longest M_III continuation after the robot's arrival [s].
        chunk_size: Episodes per result file (the unit of resumption).
    """
    split: str = "test"
    multi_human: tuple[str, ...] = MULTI_HUMAN
    single_human: tuple[str, ...] = SINGLE_HUMAN
    n_humans: int = 5
    episodes: int = 500  # per multi-human scenario
    repeats: int = 1  # per single-human offset
    visibility: str = "both"
    continuation_cap: float = 100.0  # [s] M_III continuation after the robot's arrival
    chunk_size: int = 250  # episodes per result file (the unit of resumption)

    def __post_init__(self) -> None:
        check(self.n_humans >= 1, "evaluation.n_humans", self.n_humans, "must be >= 1")
        check(self.episodes >= 1, "evaluation.episodes", self.episodes, "must be >= 1")
        check(self.repeats >= 1, "evaluation.repeats", self.repeats, "must be >= 1")
        check(self.chunk_size >= 1, "evaluation.chunk_size", self.chunk_size, "must be >= 1")
        # Upper bounds: beyond them a run cannot finish (docs/protocol.md, "Bounds").
        for name, most in (("n_humans", 1000), ("episodes", 10_000_000), ("repeats", 100_000),
                           ("chunk_size", 1_000_000)):
            value = getattr(self, name)
            check(value <= most, f"evaluation.{name}", value, f"must be <= {most}")
        for group in ("multi_human", "single_human"):
            names = getattr(self, group)
            repeated = sorted({n for n in names if names.count(n) > 1})
            check(not repeated, f"evaluation.{group}", list(names), f"lists {', '.join(repeated)} twice")
        check(
            math.isfinite(self.continuation_cap) and self.continuation_cap > 0,
            "evaluation.continuation_cap",
            self.continuation_cap,
            "must be a finite number > 0",
        )
        check(
            self.visibility in VISIBILITY_CHOICES,
            "evaluation.visibility",
            self.visibility,
            f"must be one of {', '.join(VISIBILITY_CHOICES)}",
        )


@dataclass(frozen=True)
class TrainingScenarios:
    """The scenarios the learned policies train on.

    Attributes:
        scenarios: Registered scenario names, mixed in training.
        n_humans: Humans per episode (scenarios that fix their own crowd keep it).
        visibility: ``visible`` or ``invisible``.
    """
    scenarios: tuple[str, ...] = MULTI_HUMAN
    n_humans: int = 5
    visibility: str = "invisible"

    def __post_init__(self) -> None:
        # Checked when the preset loads, so that `socialnav evaluate` refuses a preset whose training
        # section could never train as surely as `socialnav train` does.
        from socialnav.scenarios.registry import UnknownScenarioError, get_scenario

        check(len(self.scenarios) >= 1, "training.scenarios", list(self.scenarios), "must name a scenario")
        repeated = sorted({n for n in self.scenarios if self.scenarios.count(n) > 1})
        check(not repeated, "training.scenarios", list(self.scenarios), f"lists {', '.join(repeated)} twice")
        for name in self.scenarios:
            try:
                get_scenario(name)
            except UnknownScenarioError as err:
                raise ConfigError(f"training.scenarios: {err}") from None
        check(0 <= self.n_humans <= 1000, "training.n_humans", self.n_humans, "must be in [0, 1000]")
        check(
            self.visibility in VISIBILITIES,
            "training.visibility",
            self.visibility,
            f"must be one of {', '.join(VISIBILITIES)}",
        )


@dataclass(frozen=True)
class Preset:
    """A named protocol: world, robot, policy defaults, evaluation and training settings.

    Attributes:
        name: The preset's name (``wang2022``, ``francis2023``, ... or ``custom``).
        description: One line shown by ``socialnav preset list``.
        world: The simulator's settings.
        robot: The robot's body and speed.
        policies: Per-policy parameter defaults, by policy name.
        evaluation: How the protocol evaluates.
        training: What the learned policies train on.
    """
    name: str = "custom"
    description: str = ""
    world: WorldSettings = field(default_factory=WorldSettings)
    robot: RobotSettings = field(default_factory=RobotSettings)
    policies: dict[str, Any] = field(default_factory=dict)  # per-policy parameter defaults
    evaluation: EvaluationSettings = field(default_factory=EvaluationSettings)
    training: TrainingScenarios = field(default_factory=TrainingScenarios)

    def __post_init__(self) -> None:
        for policy, params in self.policies.items():
            if not isinstance(params, dict):
                raise ConfigError(
                    f"policies.{policy} must be a mapping of parameters, "
                    f"got {type(params).__name__} {params!r}"
                )

    def to_dict(self) -> dict[str, Any]:
        """The preset as nested plain dicts (``dataclasses.asdict``)."""
        return dataclasses.asdict(self)

    def policy_params(self, policy: str) -> dict[str, Any]:
        """The preset's parameter defaults of ``policy`` (a copy; empty where it sets none)."""
        return dict(self.policies.get(policy, {}))


def shipped_presets() -> list[str]:
    """The names of the presets shipped with the package, sorted."""
    return sorted(
        p.name[:-5] for p in resources.files("socialnav.configs").iterdir() if p.name.endswith(".yaml")
    )


def shipped_preset_text(name: str) -> str:
    """The YAML text of a shipped preset, comments included (a file to start one's own preset from).

    Raises:
        ConfigError: ``name`` is not a shipped preset (the shipped ones are listed).
    """
    names = shipped_presets()
    if name not in names:
        raise ConfigError(f"unknown preset {name!r}; shipped: {', '.join(names)}")
    return (resources.files("socialnav.configs") / f"{name}.yaml").read_text()


def load_preset(name_or_path: str | Path) -> Preset:
    """Loads a shipped preset by name or a YAML file by path.

    Raises:
        ConfigError: Unknown preset name (the shipped ones are listed) or invalid settings (the file
            and the dotted field are named).
    """
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml") or path.exists():
        if not path.exists():
            raise ConfigError(f"preset file {path} does not exist")
        if path.is_dir():
            raise ConfigError(f"preset {path} is a directory; give a preset name or a YAML file")
        try:
            text, source = path.read_text(), str(path)
        except UnicodeDecodeError:
            raise ConfigError(f"preset file {path} is not a text (YAML) file") from None
    else:
        text = shipped_preset_text(str(name_or_path))
        source = f"{name_or_path}.yaml"
    try:
        data = yaml.safe_load(text) or {}
    except yaml.YAMLError as err:
        raise ConfigError(f"{source}: not valid YAML: {' '.join(str(err).split())}") from None
    try:
        return from_dict(Preset, data)
    except ConfigError as err:
        raise ConfigError(f"{source}: {err}") from None
