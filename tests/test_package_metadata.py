"""Publishing metadata: the licence, the citation file, pyproject's [project] table and CI's dist check agree
with each other and with what the project ships."""

import re
from pathlib import Path

import pytest
import yaml

tomllib = pytest.importorskip("tomllib")

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())
PROJECT = PYPROJECT["project"]
CITATION = yaml.safe_load((ROOT / "CITATION.cff").read_text())
# the one place the version is written (pyproject.toml reads it through scikit-build-core's regex provider)
INIT = (ROOT / "src" / "socialnav" / "__init__.py").read_text()
VERSION = re.search(r'^__version__ = "([^"]+)"$', INIT, re.M)[1]
PAPER_TITLE = "Metrics for Evaluating Social Conformity of Crowd Navigation Algorithms"
# not for users: the test suite, the developer build, the docs site and the release tools
NOT_FOR_USERS = {"test", "dev", "dist", "docs", "all"}


def test_licence_file_matches_the_declared_licence():
    assert PROJECT["license"] == "MIT"
    assert (ROOT / "LICENSE").read_text().startswith("MIT License\n")
    for pattern in PROJECT["license-files"]:
        assert sorted(ROOT.glob(pattern)), f"license-files pattern {pattern!r} matches no file"
    # what the compiled core links in carries its notice (nanobind is linked statically)
    assert "nanobind" in (ROOT / "LICENSES" / "nanobind.txt").read_text()


def test_citation_file_cites_this_version_and_the_paper():
    assert CITATION["cff-version"] == "1.2.0"
    assert CITATION["type"] == "software"
    assert str(CITATION["version"]) == VERSION
    assert CITATION["license"] == PROJECT["license"]
    for key in ("message", "title", "authors"):
        assert CITATION[key], key
    (paper,) = [r for r in CITATION["references"] if r["title"] == PAPER_TITLE]
    assert paper["type"] == "conference-paper" and paper["year"] == 2022
    authors = [a["family-names"] for a in paper["authors"]]
    assert authors == ["Wang", "Chan", "Carreno-Medrano", "Cosgun", "Croft"]
    assert "ARSO 2022" in paper["conference"]["name"]
    assert paper["url"] == "https://arxiv.org/abs/2202.01045"


def test_version_is_written_in_one_place_and_the_changelog_lists_it():
    assert "version" not in PROJECT and "version" in PROJECT["dynamic"]
    meta = PYPROJECT["tool"]["scikit-build"]["metadata"]["version"]
    assert meta == {"provider": "scikit_build_core.metadata.regex", "input": "src/socialnav/__init__.py"}
    changelog = (ROOT / "CHANGELOG.md").read_text()
    assert re.search(rf"^## \[{re.escape(VERSION)}\] - \d{{4}}-\d{{2}}-\d{{2}}$", changelog, re.M), (
        f"CHANGELOG.md has no section for {VERSION}"
    )
    assert "## [Unreleased]" in changelog


def test_readme_says_how_to_cite_both():
    readme = (ROOT / "README.md").read_text()
    section = readme.split("## How to cite", 1)[1].split("\n## ", 1)[0]
    assert "CITATION.cff" in section and PAPER_TITLE in section and "2202.01045" in section


def test_all_extra_installs_every_user_facing_extra():
    extras = PROJECT["optional-dependencies"]
    (spec,) = extras["all"]
    m = re.fullmatch(r"socialnav\[([\w,-]+)\]", spec.replace(" ", ""))
    assert m, f"the all extra should be socialnav[...] over the other extras, not {spec!r}"
    assert set(m[1].split(",")) == set(extras) - NOT_FOR_USERS


def test_every_extra_is_in_the_docs_table():
    doc = (ROOT / "docs" / "installation.md").read_text()
    for extra in PROJECT["optional-dependencies"]:
        assert re.search(rf"^\| `{extra}` \|", doc, re.M), f"extra {extra!r}: no row in docs/installation.md"


def test_classified_python_versions_are_allowed_by_requires_python():
    low = tuple(int(x) for x in re.fullmatch(r">=(\d+)\.(\d+)", PROJECT["requires-python"]).groups())
    versions = [tuple(int(x) for x in c.rsplit(" ", 1)[1].split(".")) for c in PROJECT["classifiers"]
                if re.fullmatch(r"Programming Language :: Python :: 3\.\d+", c)]
    assert versions and min(versions) == low
    assert PROJECT["keywords"] and set(PROJECT["urls"]) >= {"Documentation", "Source", "Issues", "Changelog"}


def test_release_tools_are_pinned_and_ci_checks_the_distributions():
    lines = (ROOT / "constraints.txt").read_text().splitlines()
    pinned = {line.split("==")[0] for line in lines if "==" in line}
    for requirement in PROJECT["optional-dependencies"]["dist"]:
        assert re.match(r"[\w-]+", requirement)[0] in pinned, requirement
    ci = (ROOT / ".ci" / "run").read_text()
    assert ci.index("python -m pytest") < ci.index("tools/check_dist.sh")
