"""What the pages say holds: every shipped preset is named where presets are listed, and the learner
observation example of docs/walls_learned.md shows real points (tests/docs/test_snippets.py only
checks that the blocks run)."""

from __future__ import annotations

import re

import pytest

from socialnav.cli import build_parser
from socialnav.presets import shipped_presets

from .snippets import ROOT, blocks


def _subcommand_help(command: str, option: str) -> str:
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    action = next(a for a in sub.choices[command]._actions if option in a.option_strings)
    return action.help


@pytest.mark.parametrize("command", ["evaluate", "train"])
def test_preset_help_names_every_shipped_preset(command: str) -> None:
    text = _subcommand_help(command, "--preset")
    assert "francis2023" in shipped_presets()
    for name in shipped_presets():
        assert name in text, (command, name, text)


def test_simulator_page_names_every_shipped_preset() -> None:
    page = (ROOT / "docs" / "simulator.md").read_text(encoding="utf-8")
    keywords = page[page.index("Keywords: `scenario`") :]
    keywords = keywords[: keywords.index("\n\n")]
    for name in shipped_presets():
        assert f'`"{name}"`' in keywords, name


def test_learner_observation_example_shows_points_within_range() -> None:
    (block,) = [b for b in blocks(ROOT / "docs" / "walls_learned.md") if "LearnerObservation(" in b.code]
    namespace: dict = {}
    exec(compile(block.code, block.where, "exec"), namespace)
    mask = namespace["obs"]["obstacle_point_mask"]
    claimed = int(re.search(r'obstacle_point_mask"\]\.sum\(\)\)\s+# (\d+)', block.code)[1])
    assert 0 < int(mask.sum()) == claimed < len(mask)  # real points, and padding after them
