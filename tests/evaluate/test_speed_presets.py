"""The robot-speed presets of the reproduction (benchmarks/configs/wang2022_vpref*.yaml, issue #35)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from socialnav.presets import load_preset

CONFIGS = Path(__file__).resolve().parents[2] / "benchmarks" / "configs"


@pytest.mark.parametrize(
    ("file", "v_pref"), [("wang2022_vpref1.75.yaml", 1.75), ("wang2022_vpref2.yaml", 2.0)]
)
def test_speed_preset_is_wang2022_with_only_the_robot_speed_changed(file: str, v_pref: float) -> None:
    preset = load_preset(CONFIGS / file)
    base = load_preset("wang2022")
    assert preset.robot.v_pref == v_pref
    assert preset.name == file.removesuffix(".yaml")
    assert dataclasses.replace(preset.robot, v_pref=base.robot.v_pref) == base.robot
    for part in ("world", "evaluation", "training", "policies"):
        assert getattr(preset, part) == getattr(base, part), part
