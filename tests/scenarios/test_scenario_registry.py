"""Scenario registry: lookup, construction, parameter tables, plugins."""

from __future__ import annotations

import importlib.metadata
from dataclasses import dataclass

import numpy as np
import pytest

from socialnav.scenarios import (
    EpisodeRandom,
    HumanArrays,
    Scenario,
    UnknownScenarioError,
    get_scenario,
    list_scenarios,
    make_scenario,
    param,
    register_scenario,
)
from socialnav.scenarios import registry as reg

BUILT_IN = {
    "circle_crossing",
    "random",
    "parallel_traffic",
    "perpendicular_traffic",
    "square_crossing",
    "passing",
    "overtaking",
    "crossing",
}


@pytest.fixture
def isolated(monkeypatch: pytest.MonkeyPatch) -> None:
    """A private copy of the registry so tests can register freely."""
    monkeypatch.setattr(reg, "_REGISTRY", dict(reg._REGISTRY))
    monkeypatch.setattr(reg, "_plugins_loaded", False)


def test_built_ins_registered() -> None:
    assert set(list_scenarios()) >= BUILT_IN
    for name in BUILT_IN:
        cls = get_scenario(name)
        assert cls.name == name and issubclass(cls, Scenario)


def test_unknown_name_lists_valid() -> None:
    with pytest.raises(UnknownScenarioError, match=r"unknown scenario 'plaza'.*circle_crossing"):
        get_scenario("plaza")
    with pytest.raises(KeyError):
        make_scenario("plaza")
    with pytest.raises(ValueError, match="valid scenarios"):
        make_scenario("plaza")


def test_a_scenario_object_instead_of_its_name_says_what_to_pass() -> None:
    with pytest.raises(TypeError, match=r"must be a registered name, got a CircleCrossing: register"):
        make_scenario(make_scenario("circle_crossing"))


def test_unknown_parameter_named() -> None:
    with pytest.raises(TypeError, match=r"'n_human'.*circle_crossing.*valid parameters: n_humans"):
        make_scenario("circle_crossing", n_human=3)
    with pytest.raises(ValueError, match="traffic_area must be one of 'half_square', 'band'"):
        make_scenario("parallel_traffic", traffic_area="bands")


def test_parameter_tables() -> None:
    tables = list_scenarios()
    for name, rows in tables.items():
        names = [r.name for r in rows]
        assert len(names) == len(set(names))
        for r in rows:
            assert r.doc, f"{name}.{r.name} has no doc"
            assert r.type
    circle = {r.name: r for r in tables["circle_crossing"]}
    assert circle["n_humans"].default == 5 and circle["n_humans"].type == "int"
    assert circle["circle_radius"].default == 4.0 and circle["circle_radius"].unit == "m"
    traffic = {r.name: r for r in tables["parallel_traffic"]}
    assert traffic["traffic_area"].choices == ("half_square", "band")
    assert traffic["square_width"].default == 12.0
    assert {r.name: r for r in tables["square_crossing"]}["square_width"].default == 10.0
    passing = {r.name: r for r in tables["passing"]}
    assert passing["offset_span"].type == "float | None" and passing["n_humans"].default == 1


def test_register_and_duplicates(isolated: None) -> None:
    @register_scenario("static_line")
    @dataclass(frozen=True, kw_only=True)
    class StaticLine(Scenario):
        spacing: float = param(1.0, "spacing", unit="m", gt=0)

        def sample_humans(self, rng: EpisodeRandom, indices: np.ndarray) -> HumanArrays:
            b, n = len(rng), self.n_humans
            x = np.broadcast_to(np.arange(n) * self.spacing, (b, n))
            start = np.stack([x, np.zeros((b, n))], axis=-1)
            ones = np.ones((b, n))
            return HumanArrays(start, start + 1.0, 0.3 * ones, ones)

    assert get_scenario("static_line") is StaticLine
    bt = make_scenario("static_line", n_humans=3).episodes("val", [0, 1])
    assert bt.human_start.shape == (2, 3, 2)

    with pytest.raises(ValueError, match="already registered"):

        @register_scenario("static_line")
        @dataclass(frozen=True, kw_only=True)
        class Other(Scenario):
            def sample_humans(self, rng: EpisodeRandom, indices: np.ndarray) -> HumanArrays:
                raise NotImplementedError

    with pytest.raises(TypeError, match="Scenario subclass"):
        register_scenario("not_a_scenario")(int)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="identifier"):
        register_scenario("has space")


class _FakeEntryPoint:
    def __init__(self, name: str, obj: object = None, error: Exception | None = None) -> None:
        self.name, self.value, self._obj, self._error = name, f"pkg:{name}", obj, error

    def load(self) -> object:
        if self._error is not None:
            raise self._error
        return self._obj


def test_entry_point_plugins_lazy(isolated: None, monkeypatch: pytest.MonkeyPatch) -> None:
    @dataclass(frozen=True, kw_only=True)
    class Corridor(Scenario):
        def sample_humans(self, rng: EpisodeRandom, indices: np.ndarray) -> HumanArrays:
            b = len(rng)
            z = np.zeros((b, self.n_humans))
            s = np.stack([z + np.arange(self.n_humans), z + 1.0], axis=-1)  # 1 m apart
            return HumanArrays(s, -s, z + 0.3, z + 1.0)

    calls: list[str] = []

    def fake_entry_points(group: str) -> list[_FakeEntryPoint]:
        calls.append(group)
        return [
            _FakeEntryPoint("corridor", Corridor),
            _FakeEntryPoint("broken", error=ImportError("no module")),
        ]

    monkeypatch.setattr(importlib.metadata, "entry_points", fake_entry_points)
    get_scenario("circle_crossing")  # built-ins never trigger plugin loading
    assert calls == []
    with pytest.warns(RuntimeWarning, match="broken"):
        assert get_scenario("corridor") is Corridor
    assert calls == ["socialnav.scenarios"]
    assert Corridor.name == "corridor"
    assert "corridor" in list_scenarios()
    assert calls == ["socialnav.scenarios"]  # loaded once
    make_scenario("corridor", n_humans=2).episodes("test", [0]).validate()


def test_a_plugin_deriving_from_a_built_in_is_registered_under_its_entry_point(
        isolated: None, monkeypatch: pytest.MonkeyPatch) -> None:
    from socialnav.scenarios.square import RandomPlacement

    @dataclass(frozen=True, kw_only=True)
    class Wide(RandomPlacement):
        pass

    assert Wide.name == "random"  # inherited: it was taken for "registered itself" and dropped
    monkeypatch.setattr(importlib.metadata, "entry_points", lambda group: [_FakeEntryPoint("wide", Wide)])
    assert get_scenario("wide") is Wide and Wide.name == "wide" and "wide" in list_scenarios()
    assert get_scenario("random") is RandomPlacement  # the built-in keeps its name


def test_a_plugin_under_a_built_in_name_is_a_warning_and_the_others_still_load(
        isolated: None, monkeypatch: pytest.MonkeyPatch) -> None:
    from socialnav.scenarios.square import RandomPlacement

    @dataclass(frozen=True, kw_only=True)
    class Clash(RandomPlacement):
        pass

    @dataclass(frozen=True, kw_only=True)
    class Lane(RandomPlacement):
        pass

    monkeypatch.setattr(importlib.metadata, "entry_points", lambda group: [
        _FakeEntryPoint("circle_crossing", Clash), _FakeEntryPoint("lane", Lane)])
    with pytest.warns(RuntimeWarning, match="could not register scenario plugin 'circle_crossing'.*already "
                                            "registered"):
        assert get_scenario("lane") is Lane  # the plugin after the bad one is registered
    assert get_scenario("circle_crossing") is not Clash


def test_a_scenario_parameter_may_have_an_upper_bound() -> None:
    from socialnav.scenarios import param
    from socialnav.settings import ConfigError

    @dataclass(frozen=True, kw_only=True)
    class Bounded(Scenario):
        share: float = param(0.5, "a share", ge=0, le=1)

        def sample_humans(self, rng: EpisodeRandom, indices: np.ndarray) -> HumanArrays:
            raise NotImplementedError

    with pytest.raises(ConfigError, match="share must be in \\[0, 1\\], got 1.5"):
        Bounded(n_humans=1, share=1.5)


def test_unregistered_scenario_cannot_generate() -> None:
    @dataclass(frozen=True, kw_only=True)
    class Anonymous(Scenario):
        def sample_humans(self, rng: EpisodeRandom, indices: np.ndarray) -> HumanArrays:
            raise NotImplementedError

    with pytest.raises(TypeError, match="register_scenario"):
        Anonymous().episodes("test", [0])


def test_scenario_settings_that_are_not_a_mapping_say_what_is_expected() -> None:
    from socialnav.scenarios import scenario_from_settings

    for bad in ("circle_crossing", None):
        with pytest.raises(TypeError, match=r"must be a mapping such as \{'type': 'circle_crossing'"):
            scenario_from_settings(bad)  # type: ignore[arg-type]
