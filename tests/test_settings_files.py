"""Settings files: quoted numbers are refused alike for float and int fields, with a hint (PyYAML's
exponent forms, 1e-3 and 1.0e9, text for YAML 1.1, are accepted); an invalid training section of a
preset is refused when the preset loads, also by `socialnav evaluate`."""

from importlib import resources

import pytest
import yaml

from socialnav.presets import load_preset
from socialnav.settings import ConfigError
from socialnav.train.value.settings import load_train_settings


def _wang2022_with(tmp_path, section: str, key: str, value):
    data = yaml.safe_load((resources.files("socialnav.configs") / "wang2022.yaml").read_text())
    data[section][key] = value
    path = tmp_path / "edited.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.mark.parametrize(
    "section, key", [("robot", "v_pref"), ("world", "time_limit"), ("evaluation", "episodes")]
)
def test_quoted_numbers_are_refused_naming_the_file_and_field(tmp_path, section, key):
    path = _wang2022_with(tmp_path, section, key, "20")
    with pytest.raises(ConfigError) as err:
        load_preset(path)
    msg = str(err.value)
    assert str(path) in msg and f"{section}.{key}" in msg and "'20'" in msg and "without quotes" in msg


def test_text_that_is_no_number_gets_no_quote_hint(tmp_path):
    with pytest.raises(ConfigError, match=r"robot.v_pref must be a number, got the text 'fast'$"):
        load_preset(_wang2022_with(tmp_path, "robot", "v_pref", "fast"))


def test_pyyaml_unsigned_exponents_are_numbers(tmp_path):
    path = tmp_path / "train.yaml"
    path.write_text("rl: {lr: 1.0e-3}\nimitation: {lr: 1e-2}\n")  # 1e-2 (no dot) is text for PyYAML
    assert yaml.safe_load(path.read_text())["imitation"]["lr"] == "1e-2"
    settings = load_train_settings(path)
    assert settings.rl.lr == 1e-3 and settings.imitation.lr == 1e-2
    path.write_text("rl: {lr: 1.0e0}\n")  # unsigned exponent: text for PyYAML, accepted as 1.0
    assert yaml.safe_load(path.read_text())["rl"]["lr"] == "1.0e0"
    assert load_train_settings(path).rl.lr == 1.0


@pytest.mark.parametrize(
    "key, value, match",
    [
        ("scenarios", ["circle_crossing", "doom"], "training.scenarios: unknown scenario 'doom'"),
        ("n_humans", -3, r"training.n_humans must be in \[0, 1000\], got -3"),
        ("scenarios", [], "training.scenarios must name a scenario"),
        ("visibility", "both", "training.visibility must be one of"),
    ],
)
def test_evaluate_refuses_a_preset_whose_training_section_is_invalid(tmp_path, capsys, key, value, match):
    from socialnav.cli import main

    path = _wang2022_with(tmp_path, "training", key, value)
    with pytest.raises(ConfigError, match=match):
        load_preset(path)
    out = tmp_path / "run"
    assert main(["evaluate", "--policy", "linear", "--preset", str(path), "--episodes", "1", "--no-progress",
                 "--out", str(out)]) != 0
    assert str(path) in capsys.readouterr().err
    assert not out.exists() or not (out / "summary.json").exists()
