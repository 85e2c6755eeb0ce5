"""Every code block of README.md and docs/ runs as written (tests/docs/snippets.py says which and how):
each page in a fresh directory, its blocks in order, python blocks sharing one interpreter, `socialnav`
commands through the same Python as the tests. A block fails the test with its page and line named."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from .snippets import ROOT, Block, blocks, pages, unrunnable_commands

# Runs a page's blocks in order in one process (python blocks exec'd in one namespace, as pasted into one
# interpreter; bash blocks through bash), stopping at the first failure with its page and line.
DRIVER = r"""
import json, subprocess, sys, traceback
namespace = {"__name__": "__main__"}
outputs = {}
for block in json.load(open(sys.argv[1])):
    where = block["where"]
    print(f"--- {where} ({block['lang']})", flush=True)
    if block["lang"] == "python":
        import contextlib, io
        buffer = io.StringIO()
        try:
            with contextlib.redirect_stdout(buffer):
                exec(compile(block["code"], where, "exec"), namespace)
        except BaseException:
            print(buffer.getvalue())
            traceback.print_exc()
            print(f"FAILED {where}", flush=True)
            sys.exit(1)
        text = buffer.getvalue()
    else:
        done = subprocess.run(["bash", "-e", "-o", "pipefail", "-c", block["code"]], capture_output=True,
                              text=True)
        text = done.stdout + done.stderr
        if done.returncode != 0:
            print(text[-4000:])
            print(f"FAILED {where} (exit {done.returncode})", flush=True)
            sys.exit(1)
    print(text[-2000:], flush=True)
    outputs[where] = text
json.dump(outputs, open(sys.argv[2], "w"))
"""

PAGES = [p for p in pages() if any(b.lang in ("python", "bash") for b in blocks(p))]


def _masked(line: str) -> str:
    return re.sub(r"\d", "#", " ".join(line.split()))


def runnable(page: Path) -> tuple[list[Block], dict[str, Block]]:
    """The blocks to run and, per block, the expected output that follows it."""
    todo: list[Block] = []
    expected: dict[str, Block] = {}
    last_run: Block | None = None
    for block in blocks(page):
        if block.marker == "expect-output":
            assert last_run is not None, f"{block.where}: expect-output with no block before it to check"
            expected[last_run.where] = block
            continue
        if block.marker == "not-run":
            assert block.argument, f"{block.where}: not-run needs a reason (<!-- not-run: REASON -->)"
            continue
        if block.lang == "bash" and block.marker is None:
            bad = unrunnable_commands(block)
            assert not bad, (
                f"{block.where}: {bad[0]!r} is not a `socialnav ...` or `python FILE.py` command; "
                "mark the block <!-- not-run: REASON --> or make it runnable"
            )
        if block.lang in ("python", "bash") or block.marker == "save-as":
            todo.append(block)
            if block.marker != "save-as":
                last_run = block
    return todo, expected


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_code_blocks_run(page, tmp_path):
    todo, expected = runnable(page)
    work = tmp_path / "work"
    work.mkdir()
    run: list[dict] = []
    for block in todo:
        if block.marker == "save-as":
            (work / block.argument).write_text(block.code)
        else:
            run.append({"where": block.where, "lang": block.lang, "code": block.code})
    if not run:
        pytest.skip(f"{page.relative_to(ROOT)}: every block is marked not-run (with its reason)")
    # `socialnav` is this interpreter's socialnav (the installed package in CI, src/ in a dev build)
    shim = tmp_path / "bin"
    shim.mkdir()
    (shim / "socialnav").write_text(f'#!/bin/sh\nexec "{sys.executable}" -m socialnav.cli "$@"\n')
    (shim / "socialnav").chmod(0o755)
    (shim / "python").write_text(f'#!/bin/sh\nexec "{sys.executable}" "$@"\n')
    (shim / "python").chmod(0o755)
    env = {
        **os.environ,
        "PATH": f"{shim}{os.pathsep}{os.environ['PATH']}",
        "MPLBACKEND": "Agg",
        "OMP_NUM_THREADS": "1",
    }
    import socialnav

    package_root = str(Path(socialnav.__file__).resolve().parents[1])
    env["PYTHONPATH"] = os.pathsep.join(p for p in (package_root, str(work), env.get("PYTHONPATH", "")) if p)
    (tmp_path / "blocks.json").write_text(json.dumps(run))
    (tmp_path / "driver.py").write_text(DRIVER)
    result = subprocess.run(
        [
            sys.executable,
            str(tmp_path / "driver.py"),
            str(tmp_path / "blocks.json"),
            str(tmp_path / "out.json"),
        ],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, result.stdout[-6000:] + result.stderr[-3000:]
    outputs = json.loads((tmp_path / "out.json").read_text())
    for where, block in expected.items():
        got = {_masked(line) for line in outputs[where].splitlines()}
        for line in block.code.splitlines():
            if line.strip():
                assert _masked(line) in got, (
                    f"{block.where}: the output of {where} has no line like {line!r}; "
                    f"it printed:\n{outputs[where]}"
                )
