"""Preset sections (robot, evaluation, training) on the one settings system: a bad field of a preset
file is refused naming the file, the dotted field and the value; the recorded keys and defaults are
unchanged; every field is documented with its unit and constraint."""

from __future__ import annotations

import dataclasses
import re
import subprocess
import sys

import pytest

from socialnav.presets import (
    EvaluationSettings,
    Preset,
    RobotSettings,
    TrainingScenarios,
    load_preset,
    shipped_presets,
)
from socialnav.scenarios import SPLIT_BASES, episode_seeds
from socialnav.settings import ConfigError
from socialnav.sim import DiffDriveSettings, SensingSettings


@pytest.mark.parametrize(
    "text, message",
    [
        ("robot: {v_pref: 0}", "robot.v_pref must be in (0, 100], got 0.0"),
        ("robot: {radius: 101}", "robot.radius must be in (0, 100], got 101.0"),
        ("robot: {vpref: 1}",
         "unknown setting(s) robot.vpref (did you mean robot.v_pref?); valid: radius, v_pref"),
        ("evaluation: {chunk_size: 0}", "evaluation.chunk_size must be in [1, 1000000], got 0"),
        ("evaluation: {split: testing}",
         "evaluation.split must be one of 'val', 'test', 'train', got 'testing'"),
        ("evaluation: {visibility: seen}",
         "evaluation.visibility must be one of 'invisible', 'visible', 'both', got 'seen'"),
        ("evaluation: {continuation_cap: -1}", "evaluation.continuation_cap must be > 0, got -1.0"),
        ("evaluation: {single_human: [passing, passing]}",
         "evaluation.single_human lists passing twice, got ['passing', 'passing']"),
        ("evaluation: {episode: 3}",
         "unknown setting(s) evaluation.episode (did you mean evaluation.episodes?); valid: chunk_size, "
         "continuation_cap, episodes, multi_human, n_humans, repeats, single_human, split, visibility"),
        ("training: {visibility: both}",
         "training.visibility must be one of 'invisible', 'visible', got 'both'"),
        ("policies: {orca: 5}", "policies.orca must be a mapping of parameters, got int 5"),
    ],
)
def test_a_bad_preset_field_names_the_file_the_field_and_the_value(tmp_path, text, message):
    path = tmp_path / "mine.yaml"
    path.write_text(text + "\n")
    with pytest.raises(ConfigError) as err:
        load_preset(path)
    assert str(err.value) == f"{path}: {message}"


def test_sections_built_in_code_name_their_section():
    with pytest.raises(ConfigError, match=r"^robot.v_pref must be in \(0, 100\], got -1$"):
        RobotSettings(v_pref=-1)
    with pytest.raises(ConfigError, match=r"^evaluation.multi_human lists random twice"):
        EvaluationSettings(multi_human=("random", "circle_crossing", "random"))
    with pytest.raises(ConfigError, match=r"^training.scenarios: unknown scenario 'doom'"):
        TrainingScenarios(scenarios=("doom",))


def test_the_evaluation_split_choices_are_the_episode_splits():
    (split,) = [spec for spec in EvaluationSettings.parameters() if spec.name == "split"]
    assert split.choices == tuple(SPLIT_BASES) == ("val", "test", "train")
    for name in SPLIT_BASES:  # each choice is accepted and names episodes
        assert EvaluationSettings(split=name).split == name
        assert episode_seeds(name, [0]).tolist() == [SPLIT_BASES[name]]


def test_importing_the_presets_does_not_import_the_scenario_modules():
    # the preset takes its split choices from socialnav.scenarios.seeds; that must not load the
    # built-in scenarios' modules (the registry imports them on first lookup)
    code = (
        "import sys\n"
        "import socialnav.presets\n"
        "assert 'socialnav.scenarios.seeds' in sys.modules\n"
        "heavy = ['circle', 'francis', 'single', 'square', 'walls']\n"
        "loaded = [m for m in heavy if 'socialnav.scenarios.' + m in sys.modules]\n"
        "assert not loaded, loaded\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr


def test_the_recorded_keys_and_defaults_are_unchanged():
    # evaluation manifests and checkpoints record Preset.to_dict(): keys, order and defaults are a format
    assert RobotSettings().to_dict() == {"v_pref": 1.0, "radius": 0.3}
    multi = ("circle_crossing", "random", "parallel_traffic", "perpendicular_traffic")
    evaluation = EvaluationSettings().to_dict()
    assert evaluation == {
        "split": "test", "multi_human": multi, "single_human": ("passing", "overtaking", "crossing"),
        "n_humans": 5, "episodes": 500, "repeats": 1, "visibility": "both", "continuation_cap": 100.0,
        "chunk_size": 250,
    }
    assert list(evaluation) == ["split", "multi_human", "single_human", "n_humans", "episodes", "repeats",
                                "visibility", "continuation_cap", "chunk_size"]
    assert TrainingScenarios().to_dict() == {"scenarios": multi, "n_humans": 5, "visibility": "invisible"}
    preset = Preset().to_dict()
    assert list(preset) == ["name", "description", "world", "robot", "policies", "evaluation", "training"]
    plain = dataclasses.asdict(Preset())
    assert plain["world"].pop("human_params") is None  # added later: not recorded at their defaults
    assert plain["world"].pop("human_routes") == "none"
    assert plain["world"].pop("route_clearance") == 0.2
    assert plain["world"].pop("sensing") == dataclasses.asdict(SensingSettings())
    assert plain["world"].pop("diff_drive") == dataclasses.asdict(DiffDriveSettings())  # a diff drive's only
    assert preset == plain


@pytest.mark.parametrize("name", shipped_presets())
def test_shipped_presets_round_trip_through_to_dict(name):
    preset = load_preset(name)
    again = Preset.from_dict(preset.to_dict())
    assert again == preset and again.to_dict() == preset.to_dict()


@pytest.mark.parametrize("cls", [Preset, RobotSettings, EvaluationSettings, TrainingScenarios],
                         ids=lambda c: c.__name__)
def test_every_field_has_a_description(cls):
    assert [r.name for r in cls.parameters() if not r.doc] == []


def test_the_table_carries_units_and_constraints():
    robot = {r.name: r for r in RobotSettings.parameters()}
    assert (robot["v_pref"].unit, robot["v_pref"].constraint) == ("m/s", "in (0, 100]")
    evaluation = {r.name: r for r in EvaluationSettings.parameters()}
    assert (evaluation["continuation_cap"].unit, evaluation["continuation_cap"].constraint) == ("s", "> 0")
    assert evaluation["n_humans"].constraint == "in [1, 1000]"


def test_a_presets_scenario_and_policy_typos_are_named_with_the_file(tmp_path, capsys):
    from socialnav.cli import main
    from socialnav.policies.building import check_preset_policies
    from socialnav.presets import load_preset
    from socialnav.settings import ConfigError

    bad = tmp_path / "p1.yaml"
    bad.write_text("name: t\nevaluation:\n  multi_human: [circle_crosing]\n")
    with pytest.raises(ConfigError, match=r"p1.yaml: evaluation.multi_human: unknown scenario "
                       r"'circle_crosing'"):
        load_preset(bad)
    bad.write_text("name: t\npolicies:\n  orka: {}\n")
    with pytest.raises(ConfigError, match=r"p1.yaml: policies.orka: unknown policy 'orka'"):
        check_preset_policies(load_preset(bad), str(bad))
    bad.write_text("name: t\npolicies:\n  orca: {safty_space: 0.2}\n")
    argv = ["evaluate", "--policy", "linear", "--preset", str(bad), "--out", str(tmp_path / "o")]
    assert main(argv) == 2  # the section is checked whatever the policy evaluated
    assert ("p1.yaml: policies.orca: policy 'orca' has no parameter(s) safty_space; valid: safety_space, "
            "threads") in capsys.readouterr().err
    # values out of range, and a learned policy's settings, are named with the file too (no PyTorch needed)
    for section, message in [
        ("orca: {safety_space: -1}", "policies.orca: policy 'orca': safety_space must be >= 0, got -1"),
        ("sarl: {foo: 1}", "policies.sarl: policy 'sarl' has no parameter(s) foo; valid: device"),
        ("sarl: {planning_depth: 0}", "policies.sarl: policy 'sarl': planning_depth must be an integer >= 1"),
        ("mp_rgl: {information: psychic}", "policies.mp_rgl: policy 'mp_rgl': information must be one of"),
    ]:
        bad.write_text(f"name: t\npolicies:\n  {section}\n")
        with pytest.raises(ConfigError, match=re.escape(f"p1.yaml: {message}")):
            check_preset_policies(load_preset(bad), str(bad))


def test_an_empty_preset_file_is_refused(tmp_path):
    from socialnav.presets import load_preset
    from socialnav.settings import ConfigError

    empty = tmp_path / "my.yaml"
    empty.write_text("# only a comment\n")
    with pytest.raises(ConfigError, match=r"my.yaml: the preset file is empty \(no settings\)"):
        load_preset(empty)


def test_a_missing_optional_dependency_names_its_extra(tmp_path):
    import subprocess
    import sys

    from tests._env import subprocess_env

    # a fresh interpreter in which torch cannot be imported, as on an install without the learn extra
    code = ("import sys; sys.modules['torch'] = None; from socialnav.cli import main; "
            f"sys.exit(main(['evaluate', '--policy', 'sarl', '--scenario', 'passing', '--episodes', '2', "
            f"'--out', {str(tmp_path / 'o')!r}, '--quiet']))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=subprocess_env(),
                          check=False)
    assert done.returncode == 2, done.stderr
    assert "this needs torch, which is not installed: pip install 'socialnav[learn]'" in done.stderr
    assert not (tmp_path / "o").exists()
