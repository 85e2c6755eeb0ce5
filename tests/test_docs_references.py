"""The docs point only at files the project ships, and tools/dev_build.sh installs what it needs."""

import os
import re
import stat
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TEXT_FILES = [
    ROOT / "README.md",
    *sorted((ROOT / "docs").glob("*.md")),
    *sorted((ROOT / "src" / "socialnav").rglob("*.py")),
    *sorted((ROOT / "src" / "socialnav").rglob("*.yaml")),
    *sorted((ROOT / "src" / "socialnav").rglob("*.md")),
]


@pytest.mark.parametrize("path", TEXT_FILES, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_pointer_to_unshipped_files_or_issue_notes(path):
    text = path.read_text(encoding="utf-8")
    for pattern in (r"shared/spec", r"\bspec/\w+\.md", r"\bbaselines\.md", r"issue notes"):
        assert not re.search(pattern, text), f"{path.relative_to(ROOT)} mentions {pattern!r}"
    for ref in re.findall(r"\b((?:docs|tools|benchmarks)/[\w./-]+\.(?:md|sh|py))", text):
        assert (ROOT / ref).exists(), f"{path.relative_to(ROOT)} points at {ref}, which does not exist"


def test_dev_build_installs_nanobind_when_missing(tmp_path):
    # A stand-in `python` without nanobind that records what it is asked to pip-install.
    log = tmp_path / "calls.log"
    fake = tmp_path / "bin" / "python"
    fake.parent.mkdir()
    fake.write_text(
        "#!/usr/bin/env bash\n"
        f'echo "$*" >> {log}\n'
        'if [[ "$1 $2" == "-c import nanobind" ]]; then exit 1; fi\n'
        "exit 0\n"
    )
    fake.chmod(fake.stat().st_mode | stat.S_IEXEC)
    env = {**os.environ, "PATH": f"{fake.parent}{os.pathsep}{os.environ['PATH']}"}
    result = subprocess.run(["bash", str(ROOT / "tools" / "dev_build.sh"), "--deps-only"], env=env,
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert "-m pip install nanobind>=2.0" in log.read_text()
    assert "installing the build requirements" in result.stderr


def test_dev_build_requirements_are_declared():
    text = (ROOT / "pyproject.toml").read_text()
    assert re.search(r'^dev = \[.*"nanobind>=2\.0".*\]', text, re.M)
