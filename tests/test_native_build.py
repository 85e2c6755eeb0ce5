"""The core built by a toolchain that links libstdc++ into it (docs/installation.md, "A compiler that links
libstdc++ into the core").

Such a core holds its own copy of libstdc++ while the Python process has already loaded the system's (NumPy
links it). Exported, the copy's symbols were bound partly to the other library by the dynamic loader, and
every World crashed at its first use of iostreams (a GCC 13.3 image of Ubuntu 24.04 whose g++ links
libstdc++ statically). The core keeps the symbols of static archives inside the module: this test builds it
with ``-static-libstdc++``, checks that it exports none of libstdc++'s own symbols, and runs a world with
NumPy loaded first. It compiles the whole core (about half a minute on two cores).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

pytestmark = [
    pytest.mark.skipif(not sys.platform.startswith("linux"), reason="static libstdc++ linking: Linux only"),
    pytest.mark.skipif(shutil.which("cmake") is None or shutil.which("nm") is None,
                       reason="needs cmake (test extra) and nm (binutils)"),
]

# Runs in a fresh interpreter: NumPy (and with it the system's libstdc++) first, then the core built here.
RUN_A_WORLD = """
import sys
sys.meta_path[:] = [f for f in sys.meta_path if "ScikitBuild" not in type(f).__name__]  # an editable install
import numpy as np
from socialnav import _core
assert _core.__file__.startswith(sys.argv[1]), _core.__file__
from socialnav.scenarios import make_scenario
from socialnav.sim.settings import WorldSettings
from socialnav.sim.world import World
scenario = make_scenario("circle_crossing", n_humans=5)
world = World(WorldSettings(threads=2), scenario, 4, split="test", count=4)
world.reset()
for _ in range(20):
    world.step(np.zeros((4, 2)))
try:
    _core.World(_core.WorldConfig(), *[None] * 15)
except TypeError:
    pass
config = _core.WorldConfig()
config.batch, config.agents = 1, 2
config.human_behaviour, config.human_params = "orca", [10.0, 65, 5.0, 5.0, 0.01, 0.0]
arrays = (np.zeros((1, 2, 2)), np.zeros((1, 2, 2)), np.zeros((1, 2, 2)), np.zeros((1, 2)), np.zeros((1, 2)),
          np.zeros((1, 2), np.uint8), np.zeros(1), np.zeros(1, np.int32), np.zeros(1, np.int8), np.zeros(1),
          np.zeros(1), np.zeros(1, np.uint8), np.zeros(1, np.int32), np.zeros((1, 2)), np.zeros(1, np.int32))
try:
    _core.World(config, *arrays, None, None, None)
    raise SystemExit("no error for max_neighbors 65")
except ValueError as error:
    assert str(error) == "orca.max_neighbors must be <= 64, got 65", str(error)
print("ran")
"""


def test_a_core_with_libstdcxx_linked_in_keeps_it_inside_and_runs(tmp_path: Path) -> None:
    build = tmp_path / "build"
    env = {**os.environ, "LDFLAGS": "-static-libstdc++ -static-libgcc"}
    generator = ["-G", "Ninja"] if shutil.which("ninja") else []
    subprocess.run(["cmake", "-S", str(REPO), "-B", str(build), *generator, "-DCMAKE_BUILD_TYPE=Release",
                    f"-DPython_EXECUTABLE={sys.executable}"], env=env, check=True, capture_output=True)
    subprocess.run(["cmake", "--build", str(build), "-j", str(os.cpu_count() or 1)], env=env, check=True,
                   capture_output=True)
    core = next(build.glob("_core*.so"))
    linked = subprocess.run(["ldd", str(core)], capture_output=True, text=True).stdout
    if "libstdc++" in linked:
        pytest.skip("this toolchain did not link libstdc++ statically with -static-libstdc++")

    exported = subprocess.run(["nm", "-D", "--defined-only", str(core)], capture_output=True, text=True,
                              check=True).stdout.split("\n")
    names = [line.split()[-1] for line in exported if line.strip()]
    # Without the fix: thousands, std::ostream's members and the locale's among them.
    print(f"{len(names)} exported symbols")
    assert "PyInit__core" in names
    assert not [n for n in names if n.startswith(("_ZNSo", "_ZNSt6locale", "_ZNKSt7codecvt"))]
    assert len(names) < 500

    package = tmp_path / "src"
    shutil.copytree(REPO / "src" / "socialnav", package / "socialnav",
                    ignore=shutil.ignore_patterns("_core*.so", "__pycache__"))
    shutil.copy(core, package / "socialnav" / core.name)
    ran = subprocess.run([sys.executable, "-c", RUN_A_WORLD, str(package)], capture_output=True, text=True,
                         env={**os.environ, "PYTHONPATH": str(package)}, cwd=tmp_path, timeout=300)
    assert ran.returncode == 0, ran.stderr[-3000:]
    assert ran.stdout.strip().endswith("ran")
