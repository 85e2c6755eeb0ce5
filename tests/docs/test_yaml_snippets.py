"""The ```yaml blocks of README.md and docs/ that show a preset's ``world:`` section load as written:
every key is a world setting and every value passes its checks (a reader copies them into a preset)."""

from __future__ import annotations

import pytest
import yaml

from socialnav.settings import from_dict
from socialnav.sim.settings import WorldSettings

from .snippets import blocks, pages

WORLD_BLOCKS = [b for page in pages() for b in blocks(page)
                if b.lang == "yaml" and b.code.startswith("world:")]


def test_the_docs_show_world_sections():
    # perception, routes and kinematics each show one; a test over nothing would prove nothing
    assert {b.page for b in WORLD_BLOCKS} >= {"docs/perception.md", "docs/routes.md", "docs/kinematics.md"}


@pytest.mark.parametrize("block", WORLD_BLOCKS, ids=[b.where for b in WORLD_BLOCKS])
def test_a_world_section_of_the_docs_loads(block):
    world = from_dict(WorldSettings, yaml.safe_load(block.code)["world"], "world")
    assert isinstance(world, WorldSettings)
