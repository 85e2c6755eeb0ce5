"""Every user YAML/JSON file refuses a key given twice (PyYAML would keep the last one silently)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from socialnav._io import load_yaml
from socialnav.maps.files import MapFileError, load_map
from socialnav.presets import load_preset
from socialnav.settings import ConfigError
from socialnav.sweep.spec import load_sweep
from socialnav.train.value.settings import load_train_settings


def test_plain_yaml_reads_as_safe_load_does() -> None:
    text = "a: 1\nb: {c: [1, 2]}\nd: &base {k: 1, j: 2}\ne:\n  <<: *base\n  k: 3\nf: [{x: 1}, {x: 2}]\n"
    assert load_yaml(text) == yaml.safe_load(text)
    assert load_yaml(text)["e"] == {"k": 3, "j": 2}  # a key over a merged one is an override, not a repeat
    assert load_yaml("") is None


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("a: 1\nb: 2\na: 3\n", r"key 'a' is given twice \(lines 1 and 3\)"),
        ("world:\n  dt: 0.25\n  dt: 0.5\n", r"key 'dt' is given twice \(lines 2 and 3\)"),
        ('{"walls": [], "walls": [[[0, 0], [1, 0]]]}', r"key 'walls' is given twice \(line 1\)"),
    ],
)
def test_a_repeated_key_is_refused_with_its_lines(text: str, message: str) -> None:
    with pytest.raises(yaml.YAMLError, match=message):
        load_yaml(text)


@pytest.mark.parametrize(
    ("name", "text", "load", "error", "expected"),
    [
        ("map.yaml", "walls:\n  - [[0, 0], [1, 0]]\nwalls:\n  - [[0, 2], [1, 2]]\n", load_map, MapFileError,
         r"map.yaml: not valid YAML: key 'walls' is given twice \(lines 1 and 3\)"),
        ("map.json", '{"rectangles": [[0, 0, 1, 1]], "rectangles": [[2, 2, 3, 3]]}', load_map, MapFileError,
         r"map.json: not valid YAML: key 'rectangles' is given twice \(line 1\)"),
        ("preset.yaml", "name: mine\nworld:\n  time_limit: 30\nworld:\n  time_limit: 40\n", load_preset,
         ConfigError, r"preset.yaml: not valid YAML: key 'world' is given twice \(lines 2 and 4\)"),
        ("train.yaml", "rl:\n  episodes: 10\n  episodes: 20\n", load_train_settings, ConfigError,
         r"train.yaml: not valid YAML: key 'episodes' is given twice \(lines 2 and 3\)"),
        ("sweep.yaml", "jobs:\n  - kind: evaluate\n    policy: orca\n    policy: linear\n", load_sweep,
         ConfigError, r"sweep.yaml: not valid YAML: key 'policy' is given twice \(lines 3 and 4\)"),
    ],
)
def test_maps_presets_training_configs_and_sweeps_refuse_a_repeated_key(
    tmp_path: Path, name: str, text: str, load, error: type, expected: str
) -> None:
    # a map with two walls: blocks lost the first one silently
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(error, match=expected):
        load(path)


def test_numbers_in_scientific_notation_are_numbers(tmp_path: Path, capsys) -> None:
    # YAML 1.1 reads 1e-2 (no dot) as text; a quoted one stays text
    assert load_yaml("a: 1e-2\nb: -2E+3\nc: 1.5e-3\nd: '1e-2'\ne: e5\n") == {
        "a": 0.01, "b": -2000.0, "c": 0.0015, "d": "1e-2", "e": "e5"}
    from socialnav.evaluate.cli import parse_policy_args

    assert parse_policy_args(["safety_space=1e-2"]) == {"safety_space": 0.01}
    preset = tmp_path / "p.yaml"
    preset.write_text("name: p\npolicies:\n  orca: {safety_space: 5e-2}\n")
    assert load_preset(preset).policies["orca"]["safety_space"] == 0.05
