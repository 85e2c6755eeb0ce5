"""A worker parses each preset once, but parses an edited preset file again (Ray workers outlive sweeps)."""

from __future__ import annotations

import os
from pathlib import Path

from socialnav.sweep.tasks import _load_preset_once, job_preset


def _write(path: Path, v_pref: float) -> None:
    import importlib.resources

    base = importlib.resources.files("socialnav.configs").joinpath("wang2022.yaml").read_text()
    path.write_text(base.replace("v_pref: 1.5", f"v_pref: {v_pref}", 1))


def test_edited_preset_file_is_parsed_again(tmp_path: Path) -> None:
    path = tmp_path / "mine.yaml"
    _write(path, 1.5)
    first = _load_preset_once(str(path))
    assert _load_preset_once(str(path)) is first  # cached
    _write(path, 1.2)
    os.utime(path, ns=(os.stat(path).st_atime_ns, os.stat(path).st_mtime_ns + 10**9))
    edited = job_preset({"preset": str(path)})
    assert edited.robot.v_pref == 1.2 and first.robot.v_pref == 1.5


def test_builtin_preset_is_parsed_once() -> None:
    assert _load_preset_once("wang2022") is _load_preset_once("wang2022")
    swapped = job_preset({"preset": "wang2022", "human_model": "social_force"})
    assert swapped.world.human_model == "social_force"
    assert _load_preset_once("wang2022").world.human_model == "orca"  # the cached one is not changed
