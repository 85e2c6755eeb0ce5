"""The core built by other toolchains than the wheel's (docs/installation.md, "Other compilers and
platforms").

- **libstdc++ linked in.** Such a core holds its own copy of libstdc++ while the Python process has already
  loaded the system's (NumPy links it). Exported, the copy's symbols were bound partly to the other library
  by the dynamic loader, and every World crashed at its first use of iostreams (a GCC 13.3 image of Ubuntu
  24.04 whose g++ links libstdc++ statically). The core keeps the symbols of static archives inside the
  module: built with ``-static-libstdc++``, it must export none of libstdc++'s and run a world with NumPy
  loaded first.
- **aarch64.** Every source compiles for 64-bit Arm, where the x86 kernels' AVX2 clones must be left out.
- **Clang.** Clang refuses what GCC only warns about (a vector type passed between a function compiled with
  AVX and one without): a Clang build must compile, and step a walled world with routed humans and a lidar
  to the same bits as the installed core.

Each test compiles the whole core (about half a minute on two cores).
"""

from __future__ import annotations

import glob
import os
import re
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

pytestmark = [
    pytest.mark.skipif(not sys.platform.startswith("linux"), reason="these toolchains are checked on Linux"),
    pytest.mark.skipif(shutil.which("cmake") is None or shutil.which("nm") is None,
                       reason="needs cmake (test extra) and nm (binutils)"),
]

# The start of each script below: NumPy (and with it the system's libstdc++) first, then the core that
# sys.argv[1] names ("installed", or a package directory to import it from); sys.argv[2] is this checkout,
# where the tests' helpers are.
IMPORT_CORE = """
import sys
if sys.argv[1] != "installed":  # leave an editable install's finder out
    sys.meta_path[:] = [f for f in sys.meta_path if "ScikitBuild" not in type(f).__name__]
import numpy as np
from socialnav import _core
if sys.argv[1] != "installed":
    assert _core.__file__.startswith(sys.argv[1]), _core.__file__
sys.path.append(sys.argv[2])
"""

# Prints a digest of a walled world with routed humans and a 36-beam lidar after 60 steps of the ORCA robot
# (walls, routes, the lidar and ORCA's obstacle code: the kernels with vector types and AVX2 clones).
WORLD_DIGEST = IMPORT_CORE + """
import hashlib
from socialnav.maps.static_map import StaticMap
from socialnav.policies import make_policy
from socialnav.scenarios import make_scenario
from socialnav.sim.settings import SensingSettings, WorldSettings
from socialnav.sim.world import World
walls = StaticMap(tuple(np.array([[1.5 * np.cos(a), 1.5 * np.sin(a)], [2.5 * np.cos(a), 2.5 * np.sin(a)]])
                        for a in np.pi / 8 + np.arange(8) * np.pi / 4))
settings = WorldSettings(threads=2, human_routes="shortest", sensing=SensingSettings(lidar_beams=36))
world = World(settings, make_scenario("circle_crossing", n_humans=5), 16, split="test", count=64,
              static_map=walls)
policy = make_policy("orca", threads=2)
obs = world.reset()
digest = hashlib.sha256()
for _ in range(60):
    obs = world.step(policy.act(obs), observe=True).observation
    digest.update(np.ascontiguousarray(obs.lidar).tobytes())
for array in (world.position, world.velocity, world.status, world.reward):
    digest.update(np.ascontiguousarray(array).tobytes())
print(digest.hexdigest())
"""

# Runs a world, then asks the core for its error messages.
RUN_A_WORLD = IMPORT_CORE + """
from socialnav.scenarios import make_scenario
from socialnav.sim.settings import WorldSettings
from socialnav.sim.world import World
from tests.sim.test_behaviour_registry import _world_arrays
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
arrays = _world_arrays(1, 2)
try:
    _core.World(config, *arrays, None, None, None)
    raise SystemExit("no error for max_neighbors 65")
except ValueError as error:
    assert str(error) == "orca.max_neighbors must be <= 64, got 65", str(error)
print("ran")
"""


def build_core(tmp_path: Path, *cmake_args: str, env: dict[str, str] | None = None) -> Path:
    """Compiles the core from this checkout into tmp_path/build and returns the module's path."""
    build = tmp_path / "build"
    environment = {**os.environ, **(env or {})}
    generator = ["-G", "Ninja"] if shutil.which("ninja") else []
    configure = ["cmake", "-S", str(REPO), "-B", str(build), *generator, "-DCMAKE_BUILD_TYPE=Release",
                 f"-DPython_EXECUTABLE={sys.executable}", *cmake_args]
    configured = subprocess.run(configure, env=environment, capture_output=True, text=True)
    assert configured.returncode == 0, configured.stdout[-3000:] + configured.stderr[-3000:]
    built = subprocess.run(["cmake", "--build", str(build), "-j", str(os.cpu_count() or 1)], env=environment,
                           capture_output=True, text=True)
    assert built.returncode == 0, built.stdout[-5000:] + built.stderr[-3000:]
    return next(build.glob("_core*.so"))


def package_with(core: Path, tmp_path: Path) -> Path:
    """A copy of the Python package holding `core` as its compiled module."""
    package = tmp_path / "src"
    shutil.copytree(REPO / "src" / "socialnav", package / "socialnav",
                    ignore=shutil.ignore_patterns("_core*.so", "__pycache__"))
    shutil.copy(core, package / "socialnav" / core.name)
    return package


def run(script: str, package: Path | None, cwd: Path) -> subprocess.CompletedProcess:
    """Runs `script` in a fresh interpreter, importing socialnav from `package` (None: the installed one);
    the PYTHONPATH this process has (where dependencies may live) stays behind it."""
    env = dict(os.environ)
    if package:
        env["PYTHONPATH"] = os.pathsep.join(p for p in (str(package), os.environ.get("PYTHONPATH", "")) if p)
    return subprocess.run([sys.executable, "-c", script, str(package) if package else "installed", str(REPO)],
                          capture_output=True, text=True, env=env, cwd=cwd, timeout=300)


def clang() -> str | None:
    """A clang++ on PATH, unversioned or the newest versioned one."""
    found = shutil.which("clang++")
    if found:
        return found
    versioned = sorted(glob.glob("/usr/bin/clang++-[0-9]*"), key=lambda p: int(p.rsplit("-", 1)[1]))
    return versioned[-1] if versioned else None


def test_a_core_with_libstdcxx_linked_in_keeps_it_inside_and_runs(tmp_path: Path) -> None:
    core = build_core(tmp_path, env={"LDFLAGS": "-static-libstdc++ -static-libgcc"})
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

    ran = run(RUN_A_WORLD, package_with(core, tmp_path), tmp_path)
    assert ran.returncode == 0, ran.stderr[-3000:]
    assert ran.stdout.strip().endswith("ran")


@pytest.mark.skipif(clang() is None, reason="no clang++ on this machine (.ci/run installs it where it can)")
def test_a_clang_core_steps_a_walled_routed_world_to_the_same_bits(tmp_path: Path) -> None:
    core = build_core(tmp_path, f"-DCMAKE_CXX_COMPILER={clang()}")
    ours = run(WORLD_DIGEST, package_with(core, tmp_path), tmp_path)
    assert ours.returncode == 0, ours.stderr[-3000:]
    installed = run(WORLD_DIGEST, None, tmp_path)
    assert installed.returncode == 0, installed.stderr[-3000:]
    print(f"clang {ours.stdout.strip()}, installed {installed.stdout.strip()}")
    assert ours.stdout.strip() == installed.stdout.strip()


@pytest.mark.skipif(shutil.which("aarch64-linux-gnu-g++") is None,
                    reason="no aarch64-linux-gnu-g++ on this machine (.ci/run installs it where it can)")
def test_the_core_compiles_for_aarch64(tmp_path: Path) -> None:
    """Every source of the core compiles for 64-bit Arm (the x86 kernels' AVX2 clones and intrinsics are
    left out there), with the module's floating-point flags; the Python and nanobind headers are this
    machine's, which serve for compiling (not linking) an LP64 target."""
    nanobind = subprocess.run([sys.executable, "-m", "nanobind", "--include_dir"], capture_output=True,
                              text=True, check=True).stdout.strip()
    robin_map = Path(nanobind).parent / "ext" / "robin_map" / "include"
    includes = [f"-I{d}" for d in (REPO / "cpp", nanobind, robin_map, sysconfig.get_paths()["include"])]
    sources = sorted((REPO / "cpp").glob("*.cpp")) + sorted((REPO / "cpp" / "behaviours").glob("*.cpp"))
    # The module's own compile options (CMakeLists.txt), at -O0 in place of its -O3: compiling is checked.
    cmake_lists = (REPO / "CMakeLists.txt").read_text()
    options = re.search(r"target_compile_options\(_core PRIVATE ([^)]*)\)", cmake_lists)
    assert options, "CMakeLists.txt: no target_compile_options(_core PRIVATE ...)"
    flags = ["-std=c++17", "-O0", *[o for o in options.group(1).split() if not o.startswith("-O")], *includes]
    failed = {}
    for source in sources:
        compiled = subprocess.run(["aarch64-linux-gnu-g++", *flags, "-c", str(source), "-o",
                                   str(tmp_path / (source.stem + ".o"))], capture_output=True, text=True)
        if compiled.returncode != 0:
            failed[source.name] = compiled.stderr[-1500:]
    assert not failed, failed
    assert len(sources) >= 15
