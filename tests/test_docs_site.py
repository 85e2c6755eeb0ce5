"""The docs site builds with ``mkdocs build --strict`` (a broken link, an anchor that does not exist, a page
left out of the navigation or a docstring that names a parameter the function does not have fails), its
generated reference pages match the code, and every public name of the documented packages is in the API
reference."""

import importlib
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
# skipped only where the docs tools are not installed (`pip install ".[docs]"`; the test extra has them)
pytest.importorskip("mkdocs")
pytest.importorskip("material")
pytest.importorskip("mkdocstrings_handlers.python")

# the packages whose public names (__all__) must all appear in the API reference
DOCUMENTED = ["socialnav.sim", "socialnav.metrics", "socialnav.policies", "socialnav.logs",
              "socialnav.trajectory", "socialnav.scenarios"]
# entry points of socialnav.evaluate (a package without __all__): the ones its docs teach
EVALUATE = ["run_protocol", "ProtocolResult", "ResumeMismatchError", "load_preset", "load_episode",
            "list_episodes"]


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    out = tmp_path_factory.mktemp("site")
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    result = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)],
        cwd=ROOT, capture_output=True, text=True, env=env, timeout=600,
    )
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-6000:]
    return out


def test_the_site_builds_strictly_offline(site):
    index = (site / "index.html").read_text()
    # offline: no web font, no script or stylesheet from another host
    assert "fonts.googleapis.com" not in index and "fonts.gstatic.com" not in index
    assert not re.search(r'<(?:script|link)[^>]+(?:src|href)="https?://', index)
    assert (site / "reference" / "cli" / "index.html").exists()


def test_generated_reference_pages_match_the_code():
    result = subprocess.run([sys.executable, str(ROOT / "tools" / "gen_reference.py"), "--check"],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr


def test_every_public_name_is_in_the_api_reference(site):
    api = " ".join(p.read_text() for p in (site / "reference" / "api").rglob("*.html"))
    missing = []
    for name in DOCUMENTED:
        module = importlib.import_module(name)
        for public in getattr(module, "__all__", []):
            anywhere = re.search(rf'id="socialnav\.[\w.]+\.{public}"', api)
            if f'id="{name}.{public}"' not in api and not anywhere:
                missing.append(f"{name}.{public}")
    for public in EVALUATE:
        if not re.search(rf'id="socialnav\.[\w.]+\.{public}"', api):
            missing.append(f"socialnav.evaluate: {public}")
    assert not missing, f"not in the API reference: {', '.join(missing)}"


def test_every_page_of_docs_is_in_the_navigation():
    nav = (ROOT / "mkdocs.yml").read_text()
    pages = {str(p.relative_to(ROOT / "docs")) for p in (ROOT / "docs").rglob("*.md")}
    assert {p for p in pages if p not in nav} == set()
