"""Planners in any language (``exec:COMMAND``, docs/exec_protocol.md): the example planners in Python
(JSON lines, no socialnav import) and C++ (binary frames, compiled here) give exactly the native
``linear`` policy's results, and a misbehaving planner (a crash, a hang, a NaN action, a wrong batch
size, a wrong hello) ends the run with a one-line error naming the step, leaving a run directory that the
same command resumes."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from socialnav.cli import main

ROOT = Path(__file__).resolve().parents[2]
PY_EXAMPLE = ROOT / "examples" / "planners" / "straight_to_goal.py"
CPP_EXAMPLE = ROOT / "examples" / "planners" / "straight_to_goal.cpp"
ARGS = ["--preset", "wang2022", "--scenario", "circle_crossing", "passing", "--episodes", "6",
        "--visibility", "invisible", "--no-progress"]
#: The robots the examples drive: holonomic, and a differential drive (its twist in the frames).
ROBOTS = ["wang2022", "wang2022_diffdrive"]


def _outcomes(out: Path) -> list:
    rows = json.loads((out / "summary.json").read_text())["rows"]
    return sorted((r["scenario"], r["success_rate"], r["collision_rate"], r["nav_time_s"]) for r in rows)


def _evaluate(policy: str, out: Path, *extra: str, preset: str = "wang2022") -> int:
    args = list(ARGS)
    args[1] = preset
    return main(["evaluate", "--policy", policy, *args, "--out", str(out), *extra])


@pytest.fixture(scope="module", params=ROBOTS)
def linear_results(request, tmp_path_factory):
    out = tmp_path_factory.mktemp("linear")
    assert _evaluate("linear", out, preset=request.param) == 0
    return request.param, _outcomes(out)


def test_the_python_example_is_the_linear_policy(tmp_path, linear_results):
    preset, expected = linear_results
    out = tmp_path / "py"
    assert _evaluate(f"exec:{sys.executable} {PY_EXAMPLE}", out, preset=preset) == 0
    assert _outcomes(out) == expected
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["policy"]["protocol_version"] == 1 and manifest["policy"]["command"].endswith(".py")


def test_the_cpp_example_built_here_is_the_linear_policy(tmp_path, linear_results):
    cxx = shutil.which("c++") or shutil.which("g++") or shutil.which("clang++")
    assert cxx, "the core's build needs a C++ compiler, so the tests have one"
    binary = tmp_path / "straight_to_goal"
    subprocess.run([cxx, "-O2", "-std=c++17", "-o", str(binary), str(CPP_EXAMPLE)], check=True)
    preset, expected = linear_results
    out = tmp_path / "cpp"
    assert _evaluate(f"exec:{binary}", out, preset=preset) == 0
    assert _outcomes(out) == expected


BAD_PLANNER = '''
import json, math, os, sys, time
mode, marker = sys.argv[1], sys.argv[2]
hello = json.loads(sys.stdin.readline())
if mode == "hello":
    print(json.dumps({"protocol": "other", "version": 9, "format": "json"}), flush=True)
    sys.exit(0)
print(json.dumps({"protocol": "socialnav-exec", "version": 1, "format": "json"}), flush=True)
for step, line in enumerate(sys.stdin, start=1):
    frame = json.loads(line)
    single = len(frame["humans"][0]) == 1          # the passing cell: misbehave there
    armed = single and os.path.exists(marker)
    actions = [[0.0, 0.5] for _ in frame["robot"]]
    if armed and mode == "crash":
        sys.stderr.write("planner: out of memory\\n")
        sys.exit(3)
    if armed and mode == "hang":
        time.sleep(60)
    if armed and mode == "nan":
        actions[0][0] = math.nan
    if armed and mode == "batch":
        actions = actions[:-1]
    if armed and mode == "garbage":
        print("not json", flush=True)
        continue
    print(json.dumps({"actions": actions}), flush=True)
'''


@pytest.mark.parametrize("mode, message", [
    ("crash", r"exited with code 3; its last stderr line: 'planner: out of memory'"),
    ("hang", r"did not answer step \d+ within 1 s"),
    ("nan", r"non-finite actions .* episode\(s\) \[\d+"),
    ("batch", r"answered step \d+ with actions of shape \(\d+, 2\) for a batch of \d+ episodes"),
    ("garbage", r"answered step \d+ with 'not json'"),
])
def test_a_misbehaving_planner_ends_in_one_line_and_the_run_resumes(tmp_path, capsys, mode, message):
    import re

    script = tmp_path / "bad_planner.py"
    script.write_text(BAD_PLANNER)
    marker = tmp_path / "misbehave"
    marker.write_text("")
    policy = f"exec:{sys.executable} {script} {mode} {marker}"
    out = tmp_path / "run"
    rc = _evaluate(policy, out, "--policy-arg", "timeout=1")
    err = capsys.readouterr().err.strip()
    assert rc != 0
    last = err.splitlines()[-1]
    assert re.search(message, last), err
    assert "Traceback" not in err
    # the circle crossing's chunk was written before the planner misbehaved in the passing cell
    assert list((out / "episodes").glob("circle_crossing*")), sorted(p.name for p in out.rglob("*"))
    marker.unlink()
    assert _evaluate(policy, out, "--policy-arg", "timeout=1") == 0
    captured = capsys.readouterr()
    assert "6 episodes simulated" in captured.out + captured.err  # the passing cell only: resumed


def test_a_planner_of_another_protocol_is_refused_at_the_hello(tmp_path, capsys):
    script = tmp_path / "bad_planner.py"
    script.write_text(BAD_PLANNER)
    rc = _evaluate(f"exec:{sys.executable} {script} hello {tmp_path / 'x'}", tmp_path / "run")
    assert rc != 0
    assert "speaks protocol 'other' version 9; socialnav speaks 'socialnav-exec' version 1" in \
        capsys.readouterr().err


def test_a_missing_program_is_named(tmp_path, capsys):
    assert _evaluate("exec:./no/such/planner", tmp_path / "run") != 0
    assert "exec planner './no/such/planner' could not start" in capsys.readouterr().err


WALL_RECORDER = '''
import json, sys
out = sys.argv[1]
json.loads(sys.stdin.readline())
print(json.dumps({"protocol": "socialnav-exec", "version": 1, "format": "json"}), flush=True)
walls = {}
for line in sys.stdin:
    frame = json.loads(line)
    walls.update(frame.get("walls", {}))
    print(json.dumps({"actions": [[0.0, 0.0] for _ in frame["robot"]]}), flush=True)
    json.dump(walls, open(out, "w"))
'''


def test_the_walls_go_with_each_new_episodes_row(tmp_path):
    from socialnav.scenarios import make_scenario
    from socialnav.sim import World, WorldSettings

    script, record = tmp_path / "walls.py", tmp_path / "walls.json"
    script.write_text(WALL_RECORDER)
    rc = main(["evaluate", "--policy", f"exec:{sys.executable} {script} {record}", "--preset", "francis2023",
               "--scenario", "narrow_doorway", "--episodes", "2", "--visibility", "invisible",
               "--out", str(tmp_path / "run"), "--no-progress"])
    assert rc == 0
    walls = json.loads(record.read_text())
    with World(WorldSettings(threads=1), make_scenario("narrow_doorway"), 1, count=1) as world:
        world.reset()
        starts, ends = world.static_maps[0].edges()
    assert sorted(walls) == ["0", "1"]  # both rows' episodes brought their walls
    expected = [[*a, *b] for a, b in zip(starts.tolist(), ends.tolist(), strict=True)]
    assert walls["0"] == expected  # the doorway's fixed layout, edge by edge


TWIST_RECORDER = '''
import json, sys
out = sys.argv[1]
hello = json.loads(sys.stdin.readline())
print(json.dumps({"protocol": "socialnav-exec", "version": 1, "format": "json"}), flush=True)
twists = []
for line in sys.stdin:
    frame = json.loads(line)
    twists.append(frame["robot_twist"][0])
    print(json.dumps({"actions": [[1.0, 0.1] for _ in frame["robot"]]}), flush=True)
    json.dump({"hello": hello, "twists": twists}, open(out, "w"))
'''


def test_a_diff_drive_planner_gets_its_limits_and_twist(tmp_path):
    script, record = tmp_path / "twist.py", tmp_path / "twist.json"
    script.write_text(TWIST_RECORDER)
    rc = main(["evaluate", "--policy", f"exec:{sys.executable} {script} {record}", "--preset",
               "wang2022_diffdrive", "--scenario", "circle_crossing", "--episodes", "1", "--visibility",
               "invisible", "--out", str(tmp_path / "run"), "--no-progress"])
    assert rc == 0
    seen = json.loads(record.read_text())
    assert seen["hello"]["kinematics"] == "diff_drive"
    assert seen["hello"]["diff_drive"] == {"max_linear_acceleration": 2.5, "max_angular_acceleration": 3.2,
                                           "max_reverse_speed": 0.0}
    assert seen["hello"]["rotation_limit"] == pytest.approx(1.0471975511965976)
    # from rest, 0.625 m/s more per step up to 1 m/s; the command's 0.4 rad/s is within the window
    assert seen["twists"][:3] == [[0.0, 0.0], [0.625, 0.4], [1.0, 0.4]]
