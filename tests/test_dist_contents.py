"""tools/dist_contents.py: each rule that tools/check_dist.sh applies to the built wheel and sdist catches
what it is for, shown on small hand-made archives; and the rules read the real source tree right."""

import importlib.util
import io
import json
import tarfile
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("dist_contents", ROOT / "tools" / "dist_contents.py")
dc = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(dc)

CORE = "socialnav/_core.cpython-311-x86_64-linux-gnu.so"
WHEEL = "socialnav-0.1.0-cp311-cp311-manylinux_2_35_x86_64.whl"
DIST_INFO = "socialnav-0.1.0.dist-info/"
INDEX = """\
checkpoints:
  - {file: sarl_wang2022.pt, policy: sarl, preset: wang2022, name: sarl, label: SARL}
  - {file: rgl_wang2022.pt, policy: rgl, preset: wang2022, name: rgl, label: RGL, pending: true}
"""
SOURCE = {
    "src/socialnav/__init__.py": "",
    "src/socialnav/cli.py": "def main(): pass\n",
    "src/socialnav/py.typed": "",
    "src/socialnav/_core.pyi": "def f() -> None: ...\n",
    "src/socialnav/checkpoints/index.yaml": INDEX,
    "src/socialnav/checkpoints/sarl_wang2022.pt": "weights",
    "src/socialnav/configs/wang2022.yaml": "name: wang2022\n",
    "src/socialnav/configs/crowdnav.yaml": "name: crowdnav\n",
    "src/socialnav/configs/paper/wang2022.yaml": "table2: {}\n",
    "src/socialnav/configs/train/smoke.yaml": "rl: {}\n",
    "src/socialnav/viz/viewer.js": "(function () {})();\n",
    "src/socialnav/logs/data/example_eth_ucy.txt": "0 1 0.0 0.0\n",
    # the developer build's core and a byte-code cache: in the checkout, never expected in a wheel
    "src/socialnav/_core.cpython-311-x86_64-linux-gnu.so": "dev build",
    "src/socialnav/__pycache__/cli.cpython-311.pyc": "cache",
    "cpp/world.cpp": "int main() {}\n",
    "CMakeLists.txt": "",
    "pyproject.toml": "",
    "README.md": "",
    "CITATION.cff": "",
    "LICENSE": "MIT",
    "LICENSES/nanobind.txt": "BSD-3-Clause",
}
WHEEL_META = "Wheel-Version: 1.0\nRoot-Is-Purelib: false\nTag: cp311-cp311-manylinux_2_35_x86_64\n"


def _source(tmp_path: Path) -> Path:
    root = tmp_path / "src_tree"
    for rel, text in SOURCE.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(text)
    return root


def _complete_wheel() -> dict[str, str]:
    files = {rel[len("src/"):]: text for rel, text in SOURCE.items()
             if rel.startswith("src/socialnav/") and "__pycache__" not in rel and not rel.endswith(".so")}
    files[CORE] = "compiled"
    files.update({
        DIST_INFO + "METADATA": "Metadata-Version: 2.4\nName: socialnav\n",
        DIST_INFO + "WHEEL": WHEEL_META,
        DIST_INFO + "RECORD": "",
        DIST_INFO + "entry_points.txt": "[console_scripts]\nsocialnav = socialnav.cli:main\n",
        DIST_INFO + "licenses/LICENSE": "MIT",
        DIST_INFO + "licenses/LICENSES/nanobind.txt": "BSD-3-Clause",
    })
    return files


def _wheel(tmp_path: Path, files: dict[str, str], name: str = WHEEL) -> Path:
    path = tmp_path / name
    with zipfile.ZipFile(path, "w") as zf:
        for rel, text in files.items():
            zf.writestr(rel, text)
    return path


def _sdist(tmp_path: Path, rels: list[str]) -> Path:
    path = tmp_path / "socialnav-0.1.0.tar.gz"
    with tarfile.open(path, "w:gz") as tf:
        for rel in rels:
            data = b"x"
            info = tarfile.TarInfo(f"socialnav-0.1.0/{rel}")
            info.size = len(data)
            tf.addfile(info, io.BytesIO(data))
    return path


def _complete_sdist_files() -> list[str]:
    rels = [r for r in SOURCE if "__pycache__" not in r and not r.endswith(".so")]
    return [*rels, "PKG-INFO"]


def test_complete_wheel_and_sdist_pass(tmp_path):
    root = _source(tmp_path)
    assert dc.wheel_problems(_wheel(tmp_path, _complete_wheel()), root) == []
    assert dc.sdist_problems(_sdist(tmp_path, _complete_sdist_files()), root) == []


@pytest.mark.parametrize(("dropped", "named"), [
    ("socialnav/checkpoints/sarl_wang2022.pt", "listed in checkpoints/index.yaml"),
    ("socialnav/configs/paper/wang2022.yaml", "the paper's numbers"),
    ("socialnav/configs/wang2022.yaml", "preset wang2022"),
    ("socialnav/viz/viewer.js", "the report's episode viewer"),
    ("socialnav/_core.pyi", "the compiled core's type stub"),
    ("socialnav/py.typed", "the PEP 561 marker"),
    ("socialnav/cli.py", "a package file of the source tree"),
    (DIST_INFO + "licenses/LICENSES/nanobind.txt", "a licence or notice it must carry"),
    (DIST_INFO + "entry_points.txt", "missing"),
])
def test_a_missing_file_is_named_with_what_it_is(tmp_path, dropped, named):
    root = _source(tmp_path)
    files = _complete_wheel()
    del files[dropped]
    problems = dc.wheel_problems(_wheel(tmp_path, files), root)
    assert len(problems) == 1 and problems[0].startswith(dropped) and named in problems[0], problems


def test_run_time_data_is_demanded_even_when_gone_from_the_source_tree(tmp_path):
    root = _source(tmp_path)
    (root / "src/socialnav/configs/paper/wang2022.yaml").unlink()
    files = _complete_wheel()
    del files["socialnav/configs/paper/wang2022.yaml"]
    problems = dc.wheel_problems(_wheel(tmp_path, files), root)
    assert problems == [
        "socialnav/configs/paper/wang2022.yaml: missing (the paper's numbers (socialnav reproduce))"]


def test_a_pending_checkpoint_is_not_demanded(tmp_path):
    root = _source(tmp_path)
    assert "socialnav/checkpoints/rgl_wang2022.pt" not in dc.expected_wheel_files(root)
    assert dc.shipped_checkpoints(root) == ["socialnav/checkpoints/sarl_wang2022.pt"]


@pytest.mark.parametrize("intruder", [
    "tests/test_x.py", "benchmarks/bench_world.py", "build/cp311/CMakeCache.txt",
    "socialnav/__pycache__/cli.cpython-311.pyc", "socialnav/tests/conftest.py", "socialnav/extra_notes.txt",
])
def test_anything_beyond_the_package_is_refused(tmp_path, intruder):
    root = _source(tmp_path)
    files = {**_complete_wheel(), intruder: "x"}
    problems = dc.wheel_problems(_wheel(tmp_path, files), root)
    assert problems and all(p.startswith(intruder) for p in problems), problems


def test_the_core_must_be_there_once_and_for_the_wheels_python(tmp_path):
    root = _source(tmp_path)
    files = _complete_wheel()
    del files[CORE]
    assert any("exactly once" in p for p in dc.wheel_problems(_wheel(tmp_path, files), root))
    files[CORE.replace("311", "312")] = "compiled for 3.12"
    problems = dc.wheel_problems(_wheel(tmp_path, files), root)
    assert any("another Python than the wheel's ABI tag cp311" in p for p in problems), problems
    files[CORE] = "compiled"
    assert any("exactly once" in p for p in dc.wheel_problems(_wheel(tmp_path, files), root))


def test_wheel_metadata_must_agree_with_the_file_name(tmp_path):
    root = _source(tmp_path)
    files = _complete_wheel()
    files[DIST_INFO + "WHEEL"] = WHEEL_META.replace("manylinux_2_35_x86_64", "linux_x86_64").replace(
        "false", "true")
    problems = dc.wheel_problems(_wheel(tmp_path, files), root)
    assert any("cp311-cp311-manylinux_2_35_x86_64 not among its tags" in p for p in problems), problems
    assert any("Root-Is-Purelib: false" in p for p in problems), problems
    assert dc.wheel_problems(_wheel(tmp_path, files, name="socialnav.zip"), root)[0].endswith(
        "not a wheel file name (name-version-python-abi-platform.whl)")


def test_sdist_must_hold_the_build_inputs_and_no_build_output(tmp_path):
    root = _source(tmp_path)
    rels = [r for r in _complete_sdist_files() if r not in ("cpp/world.cpp", "LICENSES/nanobind.txt")]
    rels += ["build/cp311/_core.so", "src/socialnav/_core.cpython-311-x86_64-linux-gnu.so"]
    problems = dc.sdist_problems(_sdist(tmp_path, rels), root)
    assert sorted(problems) == sorted([
        "LICENSES/nanobind.txt: missing from the sdist",
        "cpp/world.cpp: missing from the sdist (a C++ source the build needs)",
        "build/cp311/_core.so: build output does not belong in the sdist",
        "src/socialnav/_core.cpython-311-x86_64-linux-gnu.so: build output does not belong in the sdist",
    ])


def test_command_line_exit_status_and_summary(tmp_path, capsys):
    root = _source(tmp_path)
    good = _wheel(tmp_path, _complete_wheel())
    assert dc.main(["--root", str(root), "--wheel", str(good), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["wheel"]["tag"] == "cp311-cp311-manylinux_2_35_x86_64"
    assert summary["wheel"]["bytes"] == good.stat().st_size
    files = _complete_wheel()
    del files["socialnav/viz/viewer.js"]
    bad = _wheel(tmp_path, files)
    assert dc.main(["--root", str(root), "--wheel", str(bad)]) == 1
    assert f"{WHEEL}: socialnav/viz/viewer.js: missing" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        dc.main(["--root", str(root), "--wheel", str(tmp_path / "absent.whl")])


def test_the_real_source_tree_is_read_right():
    expected = dc.expected_wheel_files(ROOT)
    index_listed = dc.shipped_checkpoints(ROOT)
    assert index_listed and all(name in expected for name in index_listed)
    # every run-time file the code reads is in the tree, so a complete wheel can exist at all
    for name in [*dc.RUNTIME_DATA, *dc.TYPING_DATA, *index_listed]:
        assert (ROOT / "src" / name).is_file(), name
    assert not [n for n in expected if n.endswith((".so", ".pyc")) or "__pycache__" in n]
    assert "socialnav/cli.py" in expected
    assert dc.licence_files(ROOT)[0] == "LICENSE" and len(dc.licence_files(ROOT)) >= 2
