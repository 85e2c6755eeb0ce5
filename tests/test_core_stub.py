"""The committed stub of the compiled core (src/socialnav/_core.pyi) is what tools/gen_core_stub.sh writes.

mypy checks every caller of ``socialnav._core`` against that stub (tools/typecheck.sh), so a binding
changed in cpp/bindings.cpp without regenerating the stub would let the type check pass on stale
signatures: this test regenerates it from the core it imports and fails on any difference.
"""

from __future__ import annotations

import difflib
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
STUB = ROOT / "src" / "socialnav" / "_core.pyi"
SCRIPT = ROOT / "tools" / "gen_core_stub.sh"


def _regenerate(out: Path) -> None:
    try:
        from socialnav import _core
    except ImportError as err:
        pytest.skip(f"the compiled core socialnav._core is not importable ({err}): build it with "
                    "tools/dev_build.sh or pip install .")
    # the folder holding the socialnav package the core came from: the dev build or an installed one
    import_root = Path(_core.__file__).resolve().parents[1]
    env = {**os.environ, "SOCIALNAV_IMPORT_ROOT": str(import_root), "PYTHON": sys.executable}
    result = subprocess.run(["bash", str(SCRIPT), str(out)], env=env, capture_output=True, text=True)
    assert result.returncode == 0, f"tools/gen_core_stub.sh failed:\n{result.stdout}{result.stderr}"


def test_the_committed_core_stub_is_current(tmp_path):
    fresh = tmp_path / "_core.pyi"
    _regenerate(fresh)
    committed, regenerated = STUB.read_text(encoding="utf-8"), fresh.read_text(encoding="utf-8")
    diff = "".join(difflib.unified_diff(committed.splitlines(True), regenerated.splitlines(True),
                                        "src/socialnav/_core.pyi (committed)", "regenerated", n=1))
    assert committed == regenerated, (
        "src/socialnav/_core.pyi is stale: run tools/gen_core_stub.sh and commit the result\n" + diff[:4000]
    )


def test_the_stub_declares_every_binding():
    # What mypy sees of the core: every name the compiled module binds (private ones included, the
    # stub is generated with -P) is declared at the stub's top level.
    try:
        from socialnav import _core
    except ImportError as err:
        pytest.skip(f"the compiled core socialnav._core is not importable ({err})")
    text = STUB.read_text(encoding="utf-8")
    bound = sorted(n for n in vars(_core) if not n.startswith("__"))
    assert {"World", "WorldConfig", "orca_step", "STATUS_RUNNING", "_silence_leak_warnings"} <= set(bound)
    missing = [n for n in bound if not re.search(rf"^(class {n}\b|def {n}\(|{n}: )", text, re.MULTILINE)]
    assert not missing, f"bound by socialnav._core but not declared in _core.pyi: {missing}"
