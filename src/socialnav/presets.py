"""Protocol presets: typed settings loaded from the YAML files shipped in ``socialnav/configs``.

A preset fixes the world's semantics, the robot, the evaluation protocol (which scenarios, how many
episodes, which visibility passes) and the training scenario mix. ``load_preset("wang2022")`` loads
a shipped one; a path to a YAML file loads a user's own.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any, ClassVar

import yaml

from socialnav._io import load_yaml
from socialnav.configs import shipped_presets
from socialnav.scenarios.seeds import SPLIT_BASES
from socialnav.settings import ConfigError, Settings, from_dict, setting
from socialnav.sim.settings import VISIBILITIES, WorldSettings

MULTI_HUMAN = ("circle_crossing", "random", "parallel_traffic", "perpendicular_traffic")
SINGLE_HUMAN = ("passing", "overtaking", "crossing")
VISIBILITY_CHOICES = (*VISIBILITIES, "both")


def _repeated(names: tuple[str, ...]) -> list[str]:
    """The names listed more than once, sorted."""
    return sorted({n for n in names if names.count(n) > 1})


@dataclass(frozen=True)
class RobotSettings(Settings):
    """The robot's body and speed."""

    section: ClassVar[str] = "robot"

    v_pref: float = setting(1.0, "preferred (and maximum) speed", unit="m/s", gt=0, le=100)
    radius: float = setting(0.3, "disc radius", unit="m", gt=0, le=100)


@dataclass(frozen=True)
class EvaluationSettings(Settings):
    """How the protocol evaluates a policy.

    The upper bounds are those beyond which a run cannot finish (docs/protocol.md, "Bounds").
    """

    section: ClassVar[str] = "evaluation"

    split: str = setting("test", "the episode split evaluated", choices=tuple(SPLIT_BASES))
    multi_human: tuple[str, ...] = setting(MULTI_HUMAN, "the multi-human scenarios")
    single_human: tuple[str, ...] = setting(
        SINGLE_HUMAN, "the single-human scenarios (one human; Table III's passing sides)"
    )
    n_humans: int = setting(5, "humans per multi-human episode", ge=1, le=1000)
    episodes: int = setting(500, "episodes per multi-human scenario", ge=1, le=10_000_000)
    repeats: int = setting(1, "episodes per single-human offset", ge=1, le=100_000)
    visibility: str = setting(
        "both", "whether the humans see the robot; both: an invisible pass, then a visible one",
        choices=VISIBILITY_CHOICES,
    )
    continuation_cap: float = setting(
        100.0, "longest M_III continuation after the robot's arrival", unit="s", gt=0
    )
    chunk_size: int = setting(
        250, "episodes per result file (the unit of resumption)", ge=1, le=1_000_000
    )

    def cross_check(self) -> None:
        """Refuses a scenario listed twice (its episodes would run, and count, twice).

        Raises:
            ConfigError: naming evaluation.multi_human or evaluation.single_human.
        """
        for group in ("multi_human", "single_human"):
            names = getattr(self, group)
            repeated = _repeated(names)
            if repeated:
                self.refuse(group, f"lists {', '.join(repeated)} twice", list(names))


@dataclass(frozen=True)
class TrainingScenarios(Settings):
    """The scenarios the learned policies train on."""

    section: ClassVar[str] = "training"

    scenarios: tuple[str, ...] = setting(MULTI_HUMAN, "registered scenario names, mixed in training")
    n_humans: int = setting(
        5, "humans per episode (scenarios that fix their own crowd keep it)", ge=0, le=1000
    )
    visibility: str = setting("invisible", "whether the humans see the robot", choices=VISIBILITIES)

    def cross_check(self) -> None:
        """Refuses an empty, repeated or unregistered scenario list.

        Checked when the preset loads, so that `socialnav evaluate` refuses a preset whose training
        section could never train as surely as `socialnav train` does.

        Raises:
            ConfigError: naming training.scenarios.
        """
        from socialnav.scenarios.registry import UnknownScenarioError, get_scenario

        if not self.scenarios:
            self.refuse("scenarios", "must name a scenario", list(self.scenarios))
        repeated = _repeated(self.scenarios)
        if repeated:
            self.refuse("scenarios", f"lists {', '.join(repeated)} twice", list(self.scenarios))
        for name in self.scenarios:
            try:
                get_scenario(name)
            except UnknownScenarioError as err:
                raise ConfigError(f"{self.section}.scenarios: {err}") from None


@dataclass(frozen=True)
class Preset(Settings):
    """A named protocol: world, robot, policy defaults, evaluation and training settings."""

    name: str = setting("custom", "the preset's name (wang2022, francis2023, ... or custom)")
    description: str = setting("", "one line shown by socialnav preset list")
    world: WorldSettings = setting(default_factory=WorldSettings, doc="the simulator's settings")
    robot: RobotSettings = setting(default_factory=RobotSettings, doc="the robot's body and speed")
    policies: dict[str, Any] = setting(
        default_factory=dict, doc="per-policy parameter defaults, by policy name (orca: {safety_space: 0.2})"
    )
    evaluation: EvaluationSettings = setting(
        default_factory=EvaluationSettings, doc="how the protocol evaluates"
    )
    training: TrainingScenarios = setting(
        default_factory=TrainingScenarios, doc="what the learned policies train on"
    )

    def cross_check(self) -> None:
        """Refuses policy defaults that are not a mapping of parameters.

        Raises:
            ConfigError: naming policies.<policy>.
        """
        for policy, params in self.policies.items():
            if not isinstance(params, dict):
                raise ConfigError(
                    f"policies.{policy} must be a mapping of parameters, "
                    f"got {type(params).__name__} {params!r}"
                )

    def policy_params(self, policy: str) -> dict[str, Any]:
        """The preset's parameter defaults of ``policy`` (a copy; empty where it sets none)."""
        return dict(self.policies.get(policy, {}))


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
        data = load_yaml(text)
    except yaml.YAMLError as err:
        raise ConfigError(f"{source}: not valid YAML: {' '.join(str(err).split())}") from None
    if data is None:  # e.g. `socialnav preset show <typo> > my.yaml` left an empty file
        raise ConfigError(f"{source}: the preset file is empty (no settings); `socialnav preset show "
                          f"wang2022 > {Path(source).name}` writes a whole preset to edit")
    try:
        preset = from_dict(Preset, data)
    except ConfigError as err:
        raise ConfigError(f"{source}: {err}") from None
    _check_names(preset, source)
    return preset


def _check_names(preset: Preset, source: str) -> None:
    """The preset's scenario names, named with the file and field.

    Checked when the preset is loaded, so that a typo is the preset's error, not one raised later
    without the file (or after part of a run). Its ``policies`` section is checked by the policies
    layer (:func:`socialnav.policies.building.check_preset_policies`), which this one may not import.
    """
    from socialnav.scenarios.registry import get_scenario

    lists = (("evaluation.multi_human", preset.evaluation.multi_human),
             ("evaluation.single_human", preset.evaluation.single_human),
             ("training.scenarios", preset.training.scenarios))
    for field, names in lists:
        for name in names:
            try:
                get_scenario(name)
            except KeyError as err:
                raise ConfigError(f"{source}: {field}: {err.args[0] if err.args else err}") from None

