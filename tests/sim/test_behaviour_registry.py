"""Pedestrian behaviours as registered components (issue #46): the built-ins' declarations, and a
behaviour written in Python, registered from outside the package, found everywhere the built-ins are:
``socialnav list``, the world settings (its parameters validated), a World's steps, and ``socialnav
evaluate`` (through an entry point of group ``socialnav.behaviours``, in a fresh process)."""

from __future__ import annotations

import importlib.util
import json
import math
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from socialnav import _core
from socialnav.cli import main
from socialnav.scenarios import make_scenario
from socialnav.settings import ConfigError
from socialnav.sim.behaviours import (
    HUMAN_MODELS,
    HumanBehaviour,
    human_behaviour,
    list_human_behaviours,
    register_human_behaviour,
    unregister_human_behaviour,
)
from socialnav.sim.settings import OrcaSettings, SocialForceSettings, WorldSettings
from socialnav.sim.world import World

# What the package outside socialnav holds: one behaviour, its parameter declared once, in the class.
PLUGIN = textwrap.dedent('''
    from dataclasses import dataclass

    from socialnav.settings import setting
    from socialnav.sim.behaviours import HumanBehaviour


    @dataclass(frozen=True)
    class HalfSpeed(HumanBehaviour):
        name = "dummy"
        description = "straight to the goal at a fraction of v_pref, ignoring everyone (a test behaviour)"

        speed_factor: float = setting(0.5, "fraction of the preferred velocity walked", gt=0, le=1)

        def velocities(self, state, preferred):
            return self.speed_factor * preferred
''')


def _plugin_module(folder: Path):
    path = folder / "dummy_behaviour.py"
    path.write_text(PLUGIN)
    spec = importlib.util.spec_from_file_location("dummy_behaviour", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture
def dummy(tmp_path):
    cls = register_human_behaviour(_plugin_module(tmp_path).HalfSpeed)
    yield cls
    unregister_human_behaviour("dummy")  # the other tests see the built-ins only


# -- the built-ins' declarations ------------------------------------------------------------------
# The parameters as sim/settings.py declared them before they were read from the core (issue #46):
# name, default, unit, constraint, description; the field order is the records' key order.
ORCA_BEFORE = [
    ("neighbor_dist", 10.0, "m", "> 0", "agents farther than this are ignored"),
    ("max_neighbors", 10, "", "in [0, 64]", "nearest agents considered"),
    ("time_horizon", 5.0, "s", "> 0", "time horizon of the velocity obstacles of agents"),
    ("time_horizon_obst", 5.0, "s", "> 0", "time horizon for static obstacles (CrowdSim's timeHorizonObst)"),
    ("radius_margin", 0.01, "m", ">= 0", "CrowdSim inflates every radius by 1 cm"),
    ("safety_space", 0.0, "m", ">= 0", "extra inflation used by the humans"),
]
SOCIAL_FORCE_BEFORE = [
    ("relaxation_time", 0.5, "s", "> 0", "tau: relaxation time towards the desired velocity"),
    ("v0", 2.1, "m^2/s^2", ">= 0", "V0: repulsion strength"),
    ("sigma", 0.3, "m", "> 0", "repulsion range"),
    ("step_time", 2.0, "s", "> 0", "delta t for the other's step"),
    ("fov_half_angle", 100.0, "deg", "", "phi: half angle of the field of view"),
    ("outside_fov_weight", 0.5, "", "in [0, 1]", "c: weight of forces from outside the field of view"),
    ("max_speed_factor", 1.3, "", "> 0", "v_max / v_desired"),
    ("wall_u0", 10.0, "m^2/s^2", ">= 0", "U0: wall repulsion strength (Helbing & Molnár 1995)"),
    ("wall_r", 0.2, "m", "> 0", "R: wall repulsion range (Helbing & Molnár 1995)"),
]


@pytest.mark.parametrize(("cls", "before"),
                         [(OrcaSettings, ORCA_BEFORE), (SocialForceSettings, SOCIAL_FORCE_BEFORE)],
                         ids=["orca", "social_force"])
def test_each_builtin_declares_the_parameters_and_defaults_it_had(cls, before):
    rows = [(p.name, p.default, p.unit, p.constraint, p.doc) for p in cls.parameters()]
    assert rows == before
    assert [type(p.default) for p in cls.parameters()] == [type(b[1]) for b in before]  # int stays int
    assert cls().to_dict() == {name: default for name, default, *_ in before}


def test_the_core_lists_the_builtins_in_order_with_their_declarations():
    natives = _core.human_behaviours()
    assert [b["name"] for b in natives] == ["orca", "social_force", "linear"]
    assert [b.name for b in list_human_behaviours()][:3] == ["orca", "social_force", "linear"]
    assert natives[2]["parameters"] == []
    orca = {p["name"]: p for p in natives[0]["parameters"]}
    assert orca["max_neighbors"] == {"name": "max_neighbors", "default": 10, "type": "int", "unit": "",
                                     "description": "nearest agents considered", "gt": None, "ge": 0,
                                     "lt": None, "le": 64}
    assert all(b["description"] for b in natives)
    assert list(HUMAN_MODELS) == ["orca", "social_force", "linear"] and "orca" in HUMAN_MODELS


def test_the_core_checks_a_behaviours_values_against_its_declaration():
    config = _core.WorldConfig()
    config.batch, config.agents = 1, 2
    arrays = _world_arrays(1, 2)
    config.human_behaviour, config.human_params = "orca", [10.0, 65, 5.0, 5.0, 0.01, 0.0]
    with pytest.raises(ValueError, match=r"orca.max_neighbors must be <= 64, got 65"):
        _core.World(config, *arrays, None, None, None)
    config.human_params = [1.0]
    with pytest.raises(ValueError, match="orca: expected 6 parameter values, got 1"):
        _core.World(config, *arrays, None, None, None)
    config.human_behaviour, config.human_params = "unknown", []
    with pytest.raises(ValueError, match="unknown pedestrian behaviour 'unknown'; registered: orca, "):
        _core.World(config, *arrays, None, None, None)
    with pytest.raises(ValueError, match="social_force declares no parameter 'tau'"):
        _core.social_force_wall_force(np.zeros(2), np.zeros((0, 2)), np.zeros(1, dtype=np.int64),
                                      {"tau": 1.0})


def _world_arrays(B: int, A: int) -> list[np.ndarray]:
    f = np.float64
    return [np.zeros((B, A, 2), f), np.zeros((B, A, 2), f), np.zeros((B, A, 2), f), np.zeros((B, A), f),
            np.zeros((B, A), f), np.zeros((B, A), np.uint8), np.zeros(B, f), np.zeros(B, np.int32),
            np.zeros(B, np.int8), np.zeros(B, f), np.zeros(B, f), np.zeros(B, np.uint8),
            np.zeros(B, np.int32), np.zeros((B, A), f), np.zeros(B, np.int32)]


def test_human_params_belong_to_behaviours_without_a_section():
    with pytest.raises(ConfigError, match=r"human_params must be empty for human_model 'orca' .*world.orca"):
        WorldSettings(human_params={"time_horizon": 2.0})
    assert WorldSettings(human_model="linear", human_params={}).human_params is None
    assert "human_params" not in WorldSettings().to_dict()  # records made before it existed stand


# -- a behaviour written in Python, registered from outside ----------------------------------------
def test_a_python_behaviour_is_listed_with_its_parameters(dummy, capsys):
    assert "dummy" in HUMAN_MODELS and human_behaviour("dummy").behaviour is dummy
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    line = next(x for x in out.splitlines() if x.startswith("  dummy"))
    assert "fraction of v_pref" in line and "speed_factor=0.5 (in (0, 1])" in line
    assert main(["list", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["human_models"] == ["orca", "social_force", "linear", "dummy"]
    entry = next(b for b in data["pedestrian_behaviours"] if b["name"] == "dummy")
    assert entry["native"] is False
    assert entry["parameters"] == [{"name": "speed_factor", "default": 0.5, "type": "float", "unit": "",
                                    "doc": "fraction of the preferred velocity walked",
                                    "constraint": "in (0, 1]"}]


def test_world_settings_validate_a_python_behaviours_parameters(dummy):
    settings = WorldSettings(human_model="dummy", human_params={"speed_factor": 0.25})
    assert settings.human_params == {"speed_factor": 0.25}
    assert settings.human_parameters() == dummy(speed_factor=0.25)
    assert WorldSettings(human_model="dummy").to_dict()["human_params"] == {"speed_factor": 0.5}
    with pytest.raises(ConfigError, match=r"^human_params.speed_factor must be in \(0, 1\], got -1"):
        WorldSettings(human_model="dummy", human_params={"speed_factor": -1})
    bad = r"^my.yaml: world.human_params.speed_factor must be in \(0, 1\], got 2"
    with pytest.raises(ConfigError, match=bad):
        WorldSettings.from_dict({"human_model": "dummy", "human_params": {"speed_factor": 2}},
                                source="my.yaml", section="world")
    with pytest.raises(ConfigError, match=r"unknown setting\(s\) human_params.sped_factor \(did you mean "
                                          r"human_params.speed_factor\?\)"):
        WorldSettings(human_model="dummy", human_params={"sped_factor": 0.5})
    # in a file's world section, the names keep their path (the message read 'world.unknown setting(s)')
    with pytest.raises(ConfigError, match=r"^my.yaml: unknown setting\(s\) world.human_params.sped_factor "
                                          r"\(did you mean world.human_params.speed_factor\?\)"):
        WorldSettings.from_dict({"human_model": "dummy", "human_params": {"sped_factor": 2}},
                                source="my.yaml", section="world")
    with pytest.raises(ConfigError, match="human_model must be one of 'orca', 'social_force', 'linear', 'd"):
        WorldSettings(human_model="dumy")


def test_a_world_moves_its_humans_as_the_python_behaviour_says(dummy):
    settings = WorldSettings(human_model="dummy", human_params={"speed_factor": 0.5}, threads=1)
    world = World(settings, make_scenario("circle_crossing", n_humans=2), 2, split="test", count=2)
    world.reset()
    world.position[:, 0], world.goal[:, 0] = (50.0, 50.0), (50.0, 60.0)  # the robot far away
    world.position[:, 1], world.goal[:, 1], world.v_pref[:, 1] = (0.0, 0.0), (0.0, 4.0), 1.0
    world.position[:, 2], world.goal[:, 2], world.v_pref[:, 2] = (3.0, 0.0), (3.0, -0.2), 1.2
    nxt = world.observe(oracle=True).next_humans  # the oracle previews the same velocities
    assert nxt[0, 0, :4].tolist() == [0.0, 0.125, 0.0, 0.5]
    for _ in range(10):
        world.step(np.zeros((2, 2)))
    # Human 1: 0.5 x 1 m/s for 10 steps of 0.25 s, straight up: 1.25 m (exact in binary).
    assert world.position[0, 1].tolist() == [0.0, 1.25]
    assert world.velocity[0, 1].tolist() == [0.0, 0.5]
    # Human 2: 0.2 m to go; the preferred velocity never passes the goal within a step (0.8 m/s, then
    # 0), walked at half of it: 0.1 m, then 0.05 m, ... halving the rest each step.
    assert world.position[1, 2, 1] == pytest.approx(-0.2 * (1 - 0.5**10), abs=1e-12)
    assert world.position[1, 2, 0] == 3.0


def test_a_python_behaviours_bad_output_is_named(dummy):
    @register_human_behaviour
    class Broken(dummy):
        name = "broken"

        def velocities(self, state, preferred):
            return np.full(state.position.shape, math.nan)

    @register_human_behaviour
    class Raising(dummy):
        name = "raising"

        def velocities(self, state, preferred):
            raise ZeroDivisionError("my behaviour broke")

    try:
        world = World(WorldSettings(human_model="broken"), make_scenario("circle_crossing", n_humans=1), 1,
                      split="test", start=7, count=1)
        world.reset()
        with pytest.raises(ValueError, match=r"behaviour 'broken' gave human 0 of episode 7 \(slot 0\) at "
                                             r"t = 0 s the non-finite velocity \(nan, nan\)"):
            world.step(np.zeros((1, 2)))
        world = World(WorldSettings(human_model="raising"), make_scenario("circle_crossing", n_humans=1), 1,
                      split="test", count=1)
        world.reset()
        with pytest.raises(RuntimeError, match="pedestrian behaviour 'raising' failed: ZeroDivisionError: my "
                                               "behaviour broke"):
            world.step(np.zeros((1, 2)))
    finally:
        unregister_human_behaviour("broken")
        unregister_human_behaviour("raising")


def test_registration_refuses_taken_names(dummy):
    with pytest.raises(ValueError, match="'orca' is a built-in one"):
        register_human_behaviour(type("Orca", (dummy,), {"name": "orca"}))
    other = type("Other", (dummy,), {})
    with pytest.raises(ValueError, match="'dummy' is registered already"):
        register_human_behaviour(other)
    with pytest.raises(TypeError, match="subclass of HumanBehaviour"):
        register_human_behaviour(object)  # type: ignore[arg-type]
    assert issubclass(dummy, HumanBehaviour)


def test_evaluate_runs_a_preset_whose_humans_follow_an_entry_point_behaviour(tmp_path):
    # A package installed beside socialnav: its module and an entry point of group socialnav.behaviours.
    site = tmp_path / "site"
    site.mkdir()
    (site / "dummy_behaviour.py").write_text(PLUGIN)
    info = site / "dummy_behaviour-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: dummy-behaviour\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[socialnav.behaviours]\ndummy = dummy_behaviour:HalfSpeed\n")
    preset = tmp_path / "tiny.yaml"
    preset.write_text(textwrap.dedent("""
        name: tiny_dummy
        description: "two humans walking at a third of their speed"
        world: {human_model: dummy, human_params: {speed_factor: 0.3333}, time_limit: 12.0}
        evaluation: {multi_human: [circle_crossing], single_human: [], n_humans: 2, episodes: 3,
                     visibility: invisible, chunk_size: 3}
        training: {scenarios: [circle_crossing], n_humans: 2}
    """))
    out = tmp_path / "run"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), *sys.path])}
    result = subprocess.run(
        [sys.executable, "-m", "socialnav", "evaluate", "--policy", "orca", "--preset", str(preset),
         "--out", str(out), "--json", "--no-progress"],
        capture_output=True, text=True, env=env, timeout=600,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["preset"]["world"]["human_model"] == "dummy"
    assert manifest["preset"]["world"]["human_params"] == {"speed_factor": 0.3333}
    rows = json.loads(result.stdout.strip().splitlines()[-1])
    assert rows  # one JSON object with the summary


def test_a_python_behaviour_reads_the_episode_time_and_index(dummy):
    # a person who walks one second and stands the next: time lives in the state, not in the behaviour
    @register_human_behaviour
    class StopAndGo(dummy):
        name = "stop_and_go"

        def velocities(self, state, preferred):
            walking = (np.floor(state.time / 1.0) % 2 == 0)[:, None, None]
            return np.where(walking, preferred, 0.0)

    try:
        scenario = make_scenario("circle_crossing", n_humans=1)
        world = World(WorldSettings(human_model="stop_and_go", dt=0.25), scenario, 1, split="test", start=3,
                      count=1)
        world.reset()
        moved = []
        for _ in range(8):
            before = world.position[0, 1].copy()
            world.step(np.zeros((1, 2)))
            moved.append(bool(np.linalg.norm(world.position[0, 1] - before) > 1e-12))
        assert moved == [True] * 4 + [False] * 4  # t = 0..0.75 s walking, 1..1.75 s standing
        from socialnav.sim.python_humans import human_state

        state = human_state(world)
        assert state.time[0] == pytest.approx(2.0) and state.episode[0] == 3
    finally:
        unregister_human_behaviour("stop_and_go")
