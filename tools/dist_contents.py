"""What the built distributions must contain, checked against the source tree.

``tools/check_dist.sh`` runs this on the wheel and sdist it builds; ``tests/test_dist_contents.py`` runs
it on small hand-made archives, so that each rule is shown to catch what it is for.

The wheel must hold every file of the package in the source tree (the modules and the data the code
reads at run time through ``importlib.resources``: presets, the paper's numbers, the shipped
checkpoints, the report's viewer, the example log), exactly one compiled core built for the wheel's own
Python, the licence, and nothing else: no tests/, benchmarks/ or build/ files, no caches, no stray
binaries. The sdist must hold everything a build needs (pyproject, CMake, the C++ sources, the package)
and no build output.

Usage: ``python tools/dist_contents.py [--root DIR] [--wheel FILE] [--sdist FILE] [--json]``; exit
status 1 with one line per problem when something is wrong.
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tarfile
import zipfile
from pathlib import Path, PurePosixPath

PACKAGE = "socialnav"
# What the code reads at run time (grep for importlib.resources in src/): each must ship, whatever the
# source tree looks like, so a file deleted by mistake is reported by name rather than silently dropped.
RUNTIME_DATA = {
    f"{PACKAGE}/checkpoints/index.yaml": "the index of the shipped checkpoints",
    f"{PACKAGE}/configs/wang2022.yaml": "preset wang2022",
    f"{PACKAGE}/configs/crowdnav.yaml": "preset crowdnav",
    f"{PACKAGE}/configs/paper/wang2022.yaml": "the paper's numbers (socialnav reproduce)",
    f"{PACKAGE}/configs/train/smoke.yaml": "training config smoke",
    f"{PACKAGE}/viz/viewer.js": "the report's episode viewer",
    f"{PACKAGE}/logs/data/example_eth_ucy.txt": "the example log (socialnav.logs.example_log)",
}
# Typing (PEP 561): the marker, and the compiled core's stub so that a user's type checker sees its
# signatures; each is demanded by name, like the run-time data.
TYPING_DATA = {
    f"{PACKAGE}/py.typed": "the PEP 561 marker (socialnav ships its types)",
    f"{PACKAGE}/_core.pyi": "the compiled core's type stub (tools/gen_core_stub.sh)",
}
# Paths that are never package content: build output and files that only make sense in a checkout.
FORBIDDEN_PARTS = {"tests", "benchmarks", "build", "dist", "__pycache__", ".ci-venv", ".git"}
FORBIDDEN_SUFFIXES = (".pyc", ".pyo", ".o", ".a")
SDIST_REQUIRED = ["pyproject.toml", "CMakeLists.txt", "README.md", "CITATION.cff", "PKG-INFO"]
WHEEL_NAME = re.compile(
    r"^(?P<name>[A-Za-z0-9_.]+)-(?P<version>[^-]+)-(?P<python>[^-]+)-(?P<abi>[^-]+)-(?P<platform>[^-]+)\.whl$"
)
CORE = re.compile(rf"^{PACKAGE}/_core\.(?P<suffix>[^/]+)\.(?:so|pyd)$")


def _tracked(root: Path, folder: str) -> list[str] | None:
    """Files git tracks under ``folder`` (None outside a git checkout, e.g. an unpacked sdist)."""
    try:
        out = subprocess.run(["git", "-C", str(root), "ls-files", "-z", "--", folder],
                             capture_output=True, check=True)
    except (OSError, subprocess.CalledProcessError):
        return None
    names = [n for n in out.stdout.decode().split("\0") if n]
    return names or None


def _is_build_output(rel: str) -> bool:
    parts = PurePosixPath(rel).parts
    return "__pycache__" in parts or rel.endswith((".so", ".pyd", *FORBIDDEN_SUFFIXES))


def package_files(root: Path) -> set[str]:
    """The package's files in the source tree, as ``socialnav/...`` (the developer build's core excluded).

    Git's list where there is one, so that an untracked scratch file in a checkout is not demanded.
    """
    src = root / "src"
    tracked = _tracked(root, f"src/{PACKAGE}")
    if tracked is not None:
        rels = [str(PurePosixPath(n).relative_to("src")) for n in tracked]
    else:
        rels = [p.relative_to(src).as_posix() for p in (src / PACKAGE).rglob("*") if p.is_file()]
    return {r for r in rels if not _is_build_output(r)}


def shipped_checkpoints(root: Path) -> list[str]:
    """Files the checkpoint index lists as shipped (entries marked ``pending`` are not expected)."""
    import yaml

    index = root / "src" / PACKAGE / "checkpoints" / "index.yaml"
    data = yaml.safe_load(index.read_text(encoding="utf-8")) or {}
    return [f"{PACKAGE}/checkpoints/{e['file']}" for e in data.get("checkpoints") or []
            if isinstance(e, dict) and "file" in e and not e.get("pending")]


def expected_wheel_files(root: Path) -> dict[str, str]:
    """Each file the wheel must contain, with what it is (for the message when it is missing)."""
    expected = {f: "a package file of the source tree" for f in package_files(root)}
    expected.update(RUNTIME_DATA)
    expected.update(TYPING_DATA)
    listed = "a shipped checkpoint listed in checkpoints/index.yaml"
    expected.update({f: listed for f in shipped_checkpoints(root)})
    return expected


def licence_files(root: Path) -> list[str]:
    """The project's licence and the notices of what its compiled core links in (``license-files``)."""
    return ["LICENSE", *sorted(p.relative_to(root).as_posix() for p in (root / "LICENSES").glob("*.txt"))]


def _forbidden(name: str) -> str | None:
    parts = PurePosixPath(name).parts
    bad = sorted(FORBIDDEN_PARTS & set(parts))
    if bad:
        return f"{name}: {bad[0]}/ files do not belong in a distribution"
    if name.endswith(FORBIDDEN_SUFFIXES):
        return f"{name}: build output does not belong in a distribution"
    return None


def wheel_problems(wheel: Path, root: Path) -> list[str]:
    """Everything wrong with ``wheel`` given the source tree at ``root`` (empty: it is complete)."""
    m = WHEEL_NAME.match(wheel.name)
    if m is None:
        return [f"{wheel.name}: not a wheel file name (name-version-python-abi-platform.whl)"]
    with zipfile.ZipFile(wheel) as zf:
        names = [n for n in zf.namelist() if not n.endswith("/")]
        dist_info = f"{m['name']}-{m['version']}.dist-info/"
        read = {n: zf.read(n).decode("utf-8", "replace") for n in names if n.startswith(dist_info)}
    problems = []
    for name in names:
        if not (name.startswith(f"{PACKAGE}/") or name.startswith(dist_info)):
            problems.append(f"{name}: outside the package and its {dist_info}")
        elif (why := _forbidden(name)) is not None:
            problems.append(why)
    present = set(names)
    for name, what in sorted(expected_wheel_files(root).items()):
        if name not in present:
            problems.append(f"{name}: missing ({what})")
    cores = [n for n in names if CORE.match(n)]
    if len(cores) != 1:
        problems.append(f"{PACKAGE}/_core: the compiled core must be there exactly once, found {cores}")
    elif m["abi"].startswith("cp") and m["abi"][2:] not in CORE.match(cores[0])["suffix"]:
        problems.append(f"{cores[0]}: built for another Python than the wheel's ABI tag {m['abi']}")
    expected = set(expected_wheel_files(root))
    for name in names:
        if name.startswith(f"{PACKAGE}/") and name not in expected and not CORE.match(name):
            problems.append(f"{name}: in the wheel but not a package file of the source tree")
    problems += _dist_info_problems(read, dist_info, m, licence_files(root))
    return problems


def _dist_info_problems(read: dict[str, str], dist_info: str, m: re.Match, licences: list[str]) -> list[str]:
    problems = []
    for required in ("METADATA", "WHEEL", "RECORD", "entry_points.txt"):
        if dist_info + required not in read:
            problems.append(f"{dist_info}{required}: missing")
    for licence in licences:
        if f"{dist_info}licenses/{licence}" not in read:
            problems.append(f"{dist_info}licenses/{licence}: missing (a licence or notice it must carry)")
    wheel_meta = read.get(dist_info + "WHEEL", "")
    tags = set(re.findall(r"^Tag: (\S+)$", wheel_meta, re.M))
    for python in m["python"].split("."):
        for platform in m["platform"].split("."):
            tag = f"{python}-{m['abi']}-{platform}"
            if wheel_meta and tag not in tags:
                problems.append(f"{dist_info}WHEEL: file name tag {tag} not among its tags {sorted(tags)}")
    if wheel_meta and "Root-Is-Purelib: false" not in wheel_meta:
        problems.append(f"{dist_info}WHEEL: a wheel with a compiled core must say Root-Is-Purelib: false")
    entry_points = read.get(dist_info + "entry_points.txt", "")
    if entry_points and not re.search(rf"^{PACKAGE}\s*=\s*{PACKAGE}\.cli:main$", entry_points, re.M):
        problems.append(f"{dist_info}entry_points.txt: no `{PACKAGE}` console script")
    return problems


def sdist_problems(sdist: Path, root: Path) -> list[str]:
    """Everything wrong with the source distribution ``sdist`` (a .tar.gz)."""
    with tarfile.open(sdist) as tf:
        names = [n.name for n in tf.getmembers() if n.isfile()]
    tops = {PurePosixPath(n).parts[0] for n in names}
    if len(tops) != 1:
        return [f"{sdist.name}: must unpack into one folder, found {sorted(tops)}"]
    top = tops.pop()
    rels = {str(PurePosixPath(n).relative_to(top)) for n in names}
    required = SDIST_REQUIRED + licence_files(root)
    problems = [f"{name}: missing from the sdist" for name in required if name not in rels]
    sources = _tracked(root, "cpp") or [p.relative_to(root).as_posix() for p in (root / "cpp").glob("*")]
    for name in sorted(sources):
        if name not in rels:
            problems.append(f"{name}: missing from the sdist (a C++ source the build needs)")
    for name in sorted(package_files(root)):
        if f"src/{name}" not in rels:
            problems.append(f"src/{name}: missing from the sdist")
    for rel in sorted(rels):
        parts = PurePosixPath(rel).parts
        if parts[0] in {"build", "dist", ".ci-venv"} or "__pycache__" in parts or rel.endswith(
            (".so", ".pyd", *FORBIDDEN_SUFFIXES)
        ):
            problems.append(f"{rel}: build output does not belong in the sdist")
    return problems


def describe(wheel: Path | None, sdist: Path | None) -> dict:
    """Sizes and tag of the checked files, for the CI log."""
    info: dict = {}
    if wheel is not None:
        with zipfile.ZipFile(wheel) as zf:
            info["wheel"] = {"file": wheel.name, "bytes": wheel.stat().st_size, "files": len(zf.namelist()),
                             "tag": "-".join(WHEEL_NAME.match(wheel.name).group("python", "abi", "platform"))}
    if sdist is not None:
        with tarfile.open(sdist) as tf:
            info["sdist"] = {"file": sdist.name, "bytes": sdist.stat().st_size, "files": len(tf.getmembers())}
    return info


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--root", type=Path, default=Path(__file__).resolve().parents[1],
                        help="the source tree the distributions were built from (default: this checkout)")
    parser.add_argument("--wheel", type=Path)
    parser.add_argument("--sdist", type=Path)
    parser.add_argument("--json", action="store_true", help="print the sizes and tag as one JSON object")
    args = parser.parse_args(argv)
    if args.wheel is None and args.sdist is None:
        parser.error("give --wheel, --sdist or both")
    for path in (args.wheel, args.sdist):
        if path is not None and not path.is_file():
            parser.error(f"{path}: no such file")
    problems = []
    if args.wheel is not None:
        problems += [f"{args.wheel.name}: {p}" for p in wheel_problems(args.wheel, args.root)]
    if args.sdist is not None:
        problems += [f"{args.sdist.name}: {p}" for p in sdist_problems(args.sdist, args.root)]
    for problem in problems:
        print(problem, file=sys.stderr)
    if problems:
        return 1
    info = describe(args.wheel, args.sdist)
    print(json.dumps(info) if args.json else "\n".join(f"{k}: {v}" for k, v in info.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
