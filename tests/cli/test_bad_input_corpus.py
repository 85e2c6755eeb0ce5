"""Bad-input corpus: every ordinary mistake is one line on stderr naming the problem, never a traceback.

Each case is a separate process (forked from one interpreter by ``forkrun.py``, so that ~80 cases
cost seconds rather than minutes) running ``socialnav.cli.main`` on a malformed input: missing,
damaged or mistyped files, settings out of range, output directories that cannot be used, a
"full disk", checkpoints that do not match the preset, directories of other runs.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.cli.fixtures import CASES, build_inputs

FORKRUN = Path(__file__).with_name("forkrun.py")


@pytest.fixture(scope="module")
def corpus(tmp_path_factory):
    base = tmp_path_factory.mktemp("corpus")
    held = build_inputs(base)  # files, directories, and a lock held on one directory
    try:
        specs = []
        for i, case in enumerate(CASES):
            work = base / "cases" / f"{i:03d}"
            work.mkdir(parents=True)
            specs.append(
                {
                    "argv": [a.format(base=base) for a in case.argv],
                    "cwd": str(work),
                    "stdout": str(work / "stdout"),
                    "stderr": str(work / "stderr"),
                    "fsize": case.fsize,
                }
            )
        (base / "cases.json").write_text(json.dumps(specs))
        result = subprocess.run(
            [sys.executable, str(FORKRUN), str(base / "cases.json"), str(base / "codes.json")],
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert result.returncode == 0, result.stderr[-3000:]
        codes = json.loads((base / "codes.json").read_text())
        out = {}
        for case, spec, code in zip(CASES, specs, codes, strict=True):
            out[case.id] = (code, Path(spec["stderr"]).read_text(), Path(spec["stdout"]).read_text(), base)
        yield out
    finally:
        held.close()
        shutil.rmtree(base / "cases", ignore_errors=True)


def test_corpus_covers_the_three_commands_and_every_class():
    assert len(CASES) >= 60
    commands = {c.argv[0] for c in CASES}
    assert commands == {"metrics", "evaluate", "train"}
    assert {c.kind for c in CASES} >= {
        "file",
        "setting",
        "bounds",
        "out",
        "checkpoint",
        "mismatch",
        "resume",
        "type",
    }
    assert len({c.id for c in CASES}) == len(CASES)


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_input_is_one_line_naming_the_problem(corpus, case):
    code, err, out, base = corpus[case.id]
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == case.code, f"exit {code}; stderr:\n{err}"
    assert "Traceback" not in err, err
    assert len(lines) == 1, f"expected one line, got:\n{err}"
    line = lines[0]
    assert line.startswith(f"socialnav {case.argv[0]}: error: "), line
    for needle in case.expect:
        assert needle.format(base=base) in line, f"{needle!r} not in {line!r}"
    for path in case.untouched:  # refused runs write nothing
        assert not (base / path).exists(), f"{path} was written"


def test_no_temporary_file_is_left_behind(corpus):
    base = next(iter(corpus.values()))[3]
    assert not [p for p in base.rglob(".*.tmp")]
