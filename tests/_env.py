"""Environment for tests that run socialnav in a subprocess.

The subprocess must import the same socialnav as the tests: the working tree's ``src`` in a
development build (``tools/dev_build.sh`` puts the native core there) and the installed package in CI
(a clean clone's ``src`` has no compiled core). Both are the directory above the imported package.
"""

from __future__ import annotations

import os
from pathlib import Path

import socialnav

PACKAGE_ROOT = Path(socialnav.__file__).resolve().parents[1]


def subprocess_env(*extra: str | os.PathLike[str], **variables: str) -> dict[str, str]:
    """``os.environ`` with PYTHONPATH = the imported package's root, then ``extra``, then the caller's."""
    parts = [str(PACKAGE_ROOT), *(str(p) for p in extra), os.environ.get("PYTHONPATH", "")]
    return {**os.environ, **variables, "PYTHONPATH": os.pathsep.join(p for p in parts if p)}
