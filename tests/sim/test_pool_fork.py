"""A forked child leaks its inherited worker pools on purpose (sim/pool.py) and says nothing about it."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs os.fork")
def test_forked_child_exits_without_a_leak_report():
    script = textwrap.dedent("""
        import os
        from socialnav.sim.pool import shared_pool
        shared_pool(2)
        pid = os.fork()
        if pid == 0:
            shared_pool(1)  # the child's own pool works; the child then exits normally
        else:
            os.waitpid(pid, 0)
    """)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=60)
    assert done.returncode == 0, done.stderr
    assert "leaked" not in done.stderr, done.stderr
