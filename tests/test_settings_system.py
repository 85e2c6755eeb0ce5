"""The one settings system (socialnav.settings): declaration, validation, loading, tables.

Hand-written cases for each promise (unknown key with the closest name, wrong type, wrong value,
nested section names, frozen instances, the parameter table's rows) and a hypothesis round trip
to_dict -> from_dict over every settings class the package declares with it.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, ClassVar

import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from socialnav.presets import EvaluationSettings, Preset, RobotSettings, TrainingScenarios
from socialnav.settings import (
    ConfigError,
    ConfigTypeError,
    Settings,
    SettingSpec,
    from_dict,
    parameter_table,
    setting,
)
from socialnav.sim.settings import OrcaSettings, RewardSettings, SocialForceSettings, WorldSettings
from socialnav.sweep.spec import EvaluateJobSettings, SweepSettings, TrainJobSettings
from socialnav.train.ppo.settings import NetworkSettings, PPOSettings
from socialnav.train.value.settings import ImitationSettings, RLSettings, TrainSettings


@dataclass(frozen=True)
class Wheel(Settings):
    """A wheel."""

    section: ClassVar[str] = "wheel"

    radius: float = setting(0.1, "wheel radius", unit="m", gt=0, le=1)
    spokes: int = setting(12, "spokes", ge=3)
    material: str = setting("steel", "what it is made of", choices=("steel", "wood"))
    even: int = setting(2, "an even number", check=lambda v: v % 2 == 0, requirement="must be even")


@dataclass(frozen=True)
class Cart(Settings):
    """A cart with two wheels."""

    speed: float = setting(1.0, "cruise speed", unit="m/s", ge=0)
    label: str | None = setting(None, "a name")
    front: Wheel = setting(default_factory=Wheel)

    def cross_check(self) -> None:
        """A cart faster than 10 m/s needs big wheels."""
        if self.speed > 10 and self.front.radius < 0.5:
            self.refuse("speed", "must be <= 10 with wheels under 0.5 m")


def test_unknown_key_is_refused_with_the_closest_name_and_the_valid_ones():
    with pytest.raises(ConfigError) as err:
        Cart.from_dict({"front": {"spoke": 10}}, source="cart.yaml", section="vehicle")
    assert str(err.value) == (
        "cart.yaml: unknown setting(s) vehicle.front.spoke (did you mean vehicle.front.spokes?); "
        "valid: even, material, radius, spokes"
    )
    with pytest.raises(ConfigError, match=r"^unknown setting\(s\) zzz; valid: front, label, speed$"):
        Cart.from_dict({"zzz": 1})  # nothing close: no suggestion


def test_wrong_types_name_the_file_the_dotted_field_and_the_value():
    with pytest.raises(ConfigError, match=r"^cart.yaml: front.radius must be a number, got the text 'big'$"):
        Cart.from_dict({"front": {"radius": "big"}}, source="cart.yaml")
    with pytest.raises(ConfigError, match=r"^front.spokes must be an integer, got the text '12' \(write"):
        Cart.from_dict({"front": {"spokes": "12"}})
    with pytest.raises(ConfigError, match=r"^section front must be a mapping of settings, got int 3$"):
        Cart.from_dict({"front": 3})
    with pytest.raises(ConfigTypeError) as err:  # built directly: also a TypeError
        Wheel(spokes=2.5)  # type: ignore[arg-type]
    assert isinstance(err.value, TypeError) and str(err.value) == "wheel.spokes must be an int, got 2.5"


@pytest.mark.parametrize(
    "data, message",
    [
        ({"speed": -1}, "cart.yaml: speed must be >= 0, got -1.0"),
        ({"speed": float("nan")}, "cart.yaml: speed must be a finite number, got nan"),
        ({"front": {"radius": 0}}, "cart.yaml: front.radius must be in (0, 1], got 0.0"),
        ({"front": {"radius": 1.5}}, "cart.yaml: front.radius must be in (0, 1], got 1.5"),
        ({"front": {"spokes": 2}}, "cart.yaml: front.spokes must be >= 3, got 2"),
        ({"front": {"material": "gold"}},
         "cart.yaml: front.material must be one of 'steel', 'wood', got 'gold'"),
        ({"front": {"even": 3}}, "cart.yaml: front.even must be even, got 3"),
        ({"speed": 11}, "cart.yaml: speed must be <= 10 with wheels under 0.5 m, got 11.0"),
    ],
)
def test_values_out_of_range_name_the_nested_field_and_the_value(data, message):
    with pytest.raises(ConfigError) as err:
        Cart.from_dict(data, source="cart.yaml")
    assert str(err.value) == message


def test_a_section_built_directly_names_itself_and_one_loaded_is_named_by_its_path():
    with pytest.raises(ConfigError, match=r"^wheel.radius must be in \(0, 1\], got -1$"):
        Wheel(radius=-1)
    with pytest.raises(ConfigError, match=r"^orca.time_horizon must be > 0, got -1.0$"):
        from_dict(WorldSettings, {"orca": {"time_horizon": -1}})
    with pytest.raises(ConfigError, match=r"^world.orca.time_horizon must be > 0, got -1.0$"):
        from_dict(WorldSettings, {"orca": {"time_horizon": -1}}, "world")
    with pytest.raises(ConfigError, match=r"^rl.batch_size must be <= rl.capacity \(50\)"):
        TrainSettings.from_dict({"rl": {"capacity": 50}})


def test_settings_are_frozen_and_keep_the_values_as_given():
    cart = Cart.from_dict({"speed": 2, "front": {"radius": 0.2}})
    with pytest.raises(dataclasses.FrozenInstanceError):
        cart.speed = 3.0  # type: ignore[misc]
    assert cart == Cart(speed=2.0, front=Wheel(radius=0.2))
    assert cart.to_dict() == {"speed": 2.0, "label": None, "front": {
        "radius": 0.2, "spokes": 12, "material": "steel", "even": 2}}
    assert Cart.from_dict(cart.to_dict()) == cart


def test_the_parameter_table_has_one_row_per_field_and_a_row_per_section():
    rows = {r.name: r for r in Cart.parameters()}
    assert list(rows) == ["speed", "label", "front", "front.radius", "front.spokes", "front.material",
                          "front.even"]
    assert rows["speed"] == SettingSpec("speed", 1.0, "float", "cruise speed", "m/s", None, ">= 0")
    assert rows["front"].is_section and rows["front"].doc == "A wheel." and rows["front"].default == Wheel()
    assert rows["front.radius"].constraint == "in (0, 1]" and rows["front.radius"].unit == "m"
    assert rows["front.material"].constraint == "one of 'steel', 'wood'"
    assert rows["front.even"].constraint == "even"
    assert rows["label"].type == "str | None"
    world = {r.name: r for r in parameter_table(WorldSettings, "world.")}
    assert world["world.orca.max_neighbors"].constraint == "in [0, 64]"
    assert world["world.rotation_limit"].constraint == "in (0, pi]"
    assert world["world.dt"].unit == "s" and world["world.dt"].default == 0.25


def test_setting_needs_check_and_requirement_together():
    with pytest.raises(TypeError, match="check= and requirement= together"):
        setting(1, "x", check=lambda v: True)


SETTINGS_CLASSES = [WorldSettings, OrcaSettings, SocialForceSettings, RewardSettings, TrainSettings,
                    ImitationSettings, RLSettings, SweepSettings, EvaluateJobSettings, TrainJobSettings,
                    PPOSettings, NetworkSettings, Preset, RobotSettings, EvaluationSettings,
                    TrainingScenarios, Cart]


@pytest.mark.parametrize("cls", SETTINGS_CLASSES, ids=lambda c: c.__name__)
def test_to_dict_is_the_plain_dataclass_dict_that_manifests_hash(cls):
    # run manifests and checkpoints record dataclasses.asdict(settings): to_dict must stay that, less the
    # settings declared record_default=False while they hold their default (added after records were made)
    instance = cls()
    plain = dataclasses.asdict(instance)
    _drop_unrecorded_defaults(instance, plain)
    assert instance.to_dict() == plain
    unrecorded = {f.name for f in dataclasses.fields(cls) if not f.metadata.get("record_default", True)}
    assert list(instance.to_dict()) == [f.name for f in dataclasses.fields(cls) if f.name not in unrecorded]


#: Settings added after records were made, with a default other than None (it then means "as before").
UNRECORDED_DEFAULTS = {"human_routes": "none", "route_clearance": 0.2,
                       "lidar_beams": 180, "lidar_range": 10.0, "lidar_history": 1, "lidar_route_goal": False,
                       "nonholonomic_log_std_init": -1.0, "turn_penalty": 0.05625,
                       "collision_penalty_ramp_start": 0.0, "collision_penalty_ramp_end": 0.0,
                       "imitation_updates": 0, "imitation_teacher": "orca_route"}
#: Sections declared with record_default=False: left out while they hold their defaults.
UNRECORDED_SECTIONS = {"sensing": "SensingSettings", "diff_drive": "DiffDriveSettings"}


def _drop_unrecorded_defaults(instance, plain):
    for f in dataclasses.fields(instance):
        value = getattr(instance, f.name)
        if not f.metadata.get("record_default", True):
            if f.name in UNRECORDED_SECTIONS:
                assert type(value).__name__ == UNRECORDED_SECTIONS[f.name] and value == type(value)()
            else:
                assert value == UNRECORDED_DEFAULTS.get(f.name)  # the others default to None
            del plain[f.name]
        elif dataclasses.is_dataclass(value):
            _drop_unrecorded_defaults(value, plain[f.name])


@dataclass(frozen=True)
class Inner(Settings):
    extra: int | None = setting(None, "added later", record_default=False)


@dataclass(frozen=True)
class Outer(Settings):
    a: float = setting(1.0, "a")
    inner: Inner = setting(default_factory=Inner)


def test_a_setting_not_recorded_at_its_default_is_recorded_once_set():
    assert Outer().to_dict() == {"a": 1.0, "inner": {}}  # the record made before `extra` existed
    assert Outer(inner=Inner(extra=3)).to_dict() == {"a": 1.0, "inner": {"extra": 3}}
    assert Outer.from_dict(Outer(inner=Inner(extra=3)).to_dict()) == Outer(inner=Inner(extra=3))


def _leaf_value(spec: SettingSpec) -> st.SearchStrategy[Any]:
    """Values inside the row's declared constraint (the table is the strategy's only input)."""
    if spec.choices:
        return st.sampled_from(spec.choices)
    base = spec.type.removesuffix(" | None")
    low, high, open_low, open_high = -1e6, 1e6, False, False
    text = spec.constraint
    for part in [] if text.startswith("in ") else text.split(", "):  # "> 0, >= 0.0001 s": the tightest
        op, _, number = part.partition(" ")
        if op in (">", ">="):
            value = float(number.split()[0])
            if value >= low:
                low, open_low = value, op == ">"
        elif op in ("<", "<="):
            high, open_high = float(number.split()[0]), op == "<"
    if text.startswith("in "):
        a, b = text[4:-1].split(", ")
        low, high = float(a), (math.pi if b == "pi" else float(b))
        open_low, open_high = text[3] == "(", text[-1] == ")"
    if base == "bool":
        strategy: st.SearchStrategy[Any] = st.booleans()
    elif base == "int":
        strategy = st.integers(math.floor(low) + 1 if open_low else math.ceil(low),
                               min(math.ceil(high) - 1 if open_high else math.floor(high), 10**6))
    elif base == "float":
        strategy = st.floats(low, high, exclude_min=open_low, exclude_max=open_high, allow_nan=False,
                             allow_infinity=False)
    elif base == "str":
        strategy = st.text(max_size=8)
    else:
        return st.just(spec.default)
    return st.one_of(st.none(), strategy) if spec.type.endswith("| None") else strategy


def _mapping_strategy(cls: type) -> st.SearchStrategy[dict[str, Any]]:
    leaves = [r for r in parameter_table(cls) if not r.is_section and r.constraint != "even"]
    return st.fixed_dictionaries({}, optional={r.name: _leaf_value(r) for r in leaves}).map(_nest)


def _nest(flat: dict[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for dotted, value in flat.items():
        *sections, name = dotted.split(".")
        node = out
        for part in sections:
            node = node.setdefault(part, {})
        node[name] = value
    return out


#: The messages of the rules between fields of the classes below (each class's cross_check).
CROSS_FIELD_RULES = ("steps per episode, more than", "<= rl.capacity", "with wheels under 0.5 m",
                     "multiple of network.attn_heads", "<= n_envs", "needs collision_penalty",
                     "<= collision_penalty_ramp_end")


@pytest.mark.parametrize("cls", [WorldSettings, TrainSettings, SweepSettings, EvaluateJobSettings,
                                 TrainJobSettings, PPOSettings, Preset, Cart], ids=lambda c: c.__name__)
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_from_dict_of_to_dict_is_the_identity(cls, data):
    mapping = data.draw(_mapping_strategy(cls))
    try:
        instance = cls.from_dict(mapping)
    except ConfigError as err:  # only a rule between fields (cross_check) may refuse in-range values
        assert any(rule in str(err) for rule in CROSS_FIELD_RULES), str(err)
        assume(False)
        return
    again = cls.from_dict(instance.to_dict())
    assert again == instance and again.to_dict() == instance.to_dict()


def test_a_preset_names_a_nested_world_section_once(tmp_path):
    # before the one settings system this read "world.orca.orca.time_horizon"
    from importlib import resources

    import yaml

    from socialnav.presets import load_preset

    data = yaml.safe_load((resources.files("socialnav.configs") / "wang2022.yaml").read_text())
    data["world"].setdefault("orca", {})["time_horizon"] = -1
    path = tmp_path / "wang.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError) as err:
        load_preset(path)
    assert str(err.value) == f"{path}: world.orca.time_horizon must be > 0, got -1.0"
