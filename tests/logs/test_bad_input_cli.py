"""Bad-input corpus through `socialnav metrics` as subprocesses: one clear line, exit != 0, no traceback."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from tests._env import subprocess_env

HEADER = "t,id,x,y,role"


def _rows(n: int = 4, dt: float = 0.4) -> list[str]:
    out = [HEADER]
    for k in range(n):
        out.append(f"{k * dt:.2f},0,0.0,{0.4 * k:.2f},robot")
        out.append(f"{k * dt:.2f},1,1.0,{4 - 0.4 * k:.2f},human")
    return out


def _csv(tmp: Path, name: str, lines: list[str]) -> Path:
    path = tmp / name
    path.write_text("\n".join(lines) + "\n")
    return path


def _eth(tmp: Path, name: str, text: str) -> Path:
    path = tmp / name
    path.write_text(text)
    return path


def _cases(tmp: Path) -> list[tuple[str, list[str], list[str], int]]:
    """(case, argv, words the message must contain, expected exit status)."""
    ok = _rows()
    good_eth = "".join(f"{10 * k}\t{i}\t{1.0 * i}\t{0.5 * k}\n" for k in range(5) for i in (1, 2))
    parquet_bad = tmp / "corrupt.parquet"
    parquet_bad.write_bytes(b"PAR1\x00\x01garbage" * 10)
    binary = tmp / "binary.csv"
    binary.write_bytes(bytes(range(256)) * 8)
    (tmp / "a_directory.csv").mkdir()
    (tmp / "empty.csv").write_text("")
    liar = ["t,id,x,y,role,gx,gy,outcome"] + [
        line for k in range(4) for line in (f"{0.4 * k:.1f},0,0.0,{0.4 * k:.1f},robot,0.0,8.7,success",
                                            f"{0.4 * k:.1f},1,0.2,0.8,human,0.2,0.8,success")]
    speeds = [HEADER] + [f"{k * 0.4:.2f},0,0.0,{400.0 * k},robot" for k in range(4)]  # millimetres?
    dup = ok + ["0.40,1,1.0,3.6,human"]
    backwards = [HEADER, "0.0,0,0,0,robot", "0.4,0,0,0.4,robot", "0.2,0,0,0.8,robot", "0.0,1,1,4,human",
                 "0.4,1,1,3.6,human"]
    return [
        ("missing column", [str(_csv(tmp, "nocol.csv", [r.rsplit(",", 2)[0] + ",robot" for r in ok]))],
         ["nocol.csv", "no column for ['y']"], 2),
        ("mapped column absent", [str(_csv(tmp, "m.csv", ok)), "--columns", "x=px"],
         ["m.csv", "'px'", "not found"], 2),
        ("unknown mapping field", [str(_csv(tmp, "f.csv", ok)), "--columns", "speed=x"],
         ["unknown field 'speed'"], 2),
        ("malformed mapping", [str(_csv(tmp, "g.csv", ok)), "--columns", "time"],
         ["expected field=column"], 2),
        ("duplicated (time, id)", [str(_csv(tmp, "dup.csv", dup))], ["dup.csv", "column 't'", "row 9",
                                                                      "duplicated"], 2),
        ("NaN position", [str(_csv(tmp, "nan.csv", ok[:3] + ["0.40,0,nan,0.4,robot"] + ok[4:]))],
         ["nan.csv", "column 'x'", "row 3", "missing"], 2),
        ("empty cell", [str(_csv(tmp, "hole.csv", ok[:3] + ["0.40,0,,0.4,robot"] + ok[4:]))],
         ["hole.csv", "column 'x'", "row 3"], 2),
        ("inf position", [str(_csv(tmp, "inf.csv", ok[:5] + ["0.80,0,0.0,inf,robot"] + ok[6:]))],
         ["inf.csv", "column 'y'", "row 5", "inf"], 2),
        ("non-numeric", [str(_csv(tmp, "text.csv", ok[:2] + ["0.00,1,one,4.0,human"] + ok[3:]))],
         ["text.csv", "column 'x'", "row 2", "'one'"], 2),
        ("time going backwards", [str(_csv(tmp, "back.csv", backwards))],
         ["back.csv", "column 't'", "row 3", "backwards"], 2),
        ("implausible speed", [str(_csv(tmp, "fast.csv", speeds))],
         ["fast.csv", "column 'x'", "row 2", "implausible speed", "metres"], 2),
        ("empty file", [str(tmp / "empty.csv")], ["empty.csv", "empty file"], 2),
        ("header only", [str(_csv(tmp, "header.csv", [HEADER]))], ["header.csv", "no data rows"], 2),
        ("binary named .csv", [str(binary)], ["binary.csv", "binary"], 2),
        ("directory", [str(tmp / "a_directory.csv")], ["a_directory.csv", "directory"], 2),
        ("no such file", [str(tmp / "nowhere.csv")], ["nowhere.csv", "no such file"], 2),
        ("corrupt parquet", [str(parquet_bad)], ["corrupt.parquet", "cannot be read"], 2),
        ("unknown suffix", [str(_csv(tmp, "log.json", ok))], ["log.json", "--format"], 2),
        ("no robot, no ego", [str(_csv(tmp, "peds.csv", [r.rsplit(",", 1)[0] for r in ok])).replace(
            "peds.csv", "peds.csv")], ["peds.csv", "no robot", "--ego"], 2),
        ("ego id absent", [str(_csv(tmp, "e.csv", ok)), "--ego", "42"], ["e.csv", "42"], 2),
        ("bad role", [str(_csv(tmp, "role.csv", ok[:2] + ["0.00,1,1.0,4.0,pilot"] + ok[3:]))],
         ["role.csv", "column 'role'", "row 2", "pilot"], 2),
        ("eth-ucy wrong field count", [str(_eth(tmp, "three.txt", "10\t1\t2.0\n")), "--ego", "all"],
         ["three.txt", "line 1", "expected 4 fields"], 2),
        ("eth-ucy non-numeric", [str(_eth(tmp, "word.txt", good_eth + "60\tfoo\t1\t2\n")), "--ego", "all"],
         ["word.txt", "column 'id'", "line 11", "foo"], 2),
        ("eth-ucy without ego", [str(_eth(tmp, "noego.txt", good_eth))],
         ["noego.txt", "no robot", "--ego"], 2),
        ("single-sample ego", [str(_eth(tmp, "one.txt", good_eth + "40\t9\t5.0\t5.0\n")), "--ego", "9"],
         ["one.txt", "agent 9", "line 11", "1 sample"], 2),
        ("single-sample agent among egos (scored, warned)",
         [str(_eth(tmp, "some.txt", good_eth + "40\t9\t5.0\t5.0\n")), "--ego", "all"],
         ["some.txt", "not scored as ego", "agent 9", "line 11"], 1),
        ("success label contradicted", [str(_csv(tmp, "liar.csv", liar)), "--radius", "0.3"],
         ["liar.csv", "labelled 'success'", "overlaps agent 1", "7.5 m from its goal"], 1),
        ("negative dt", [str(_csv(tmp, "dt.csv", ok)), "--dt", "-1"], ["dt must be > 0"], 2),
        ("long format, irregular without --resample", [str(_csv(tmp, "long.csv", [
            "episode,t,agent,x,y,radius,gx,gy,v_pref", "0,0.0,0,0,0,0.3,0,1,1", "0,0.1,0,0,0.1,0.3,0,1,1",
            "0,0.3,0,0,0.3,0.3,0,1,1"]))], ["long.csv", "column 't'", "row 2", "resample"], 2),
    ]


def test_bad_input_corpus(tmp_path: Path) -> None:
    cases = _cases(tmp_path)
    assert len(cases) >= 20
    env = subprocess_env()
    failures = []
    for name, argv, words, status in cases:
        proc = subprocess.run([sys.executable, "-m", "socialnav.cli", "metrics", *argv], capture_output=True,
                              text=True, env=env, timeout=120)
        err = proc.stderr
        problems = []
        if proc.returncode != status:
            problems.append(f"exit {proc.returncode} != {status}")
        if "Traceback" in err:
            problems.append("traceback")
        lines = [ln for ln in err.splitlines() if ln.startswith(("socialnav metrics: error", "warning"))]
        if not lines:
            problems.append("no error/warning line")
        missing = [w for w in words if not any(w in line for line in lines)]
        if missing:
            problems.append(f"message lacks {missing}")
        if status == 2 and len(err.strip().splitlines()) != 1:
            problems.append("not one line")
        if problems:
            failures.append(f"{name}: {problems}\n{err}")
    assert not failures, "\n".join(failures)


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_format_flag_mismatch(tmp_path: Path, fmt: str) -> None:
    path = _csv(tmp_path, "x.csv" if fmt == "parquet" else "x.parquet", _rows())
    proc = subprocess.run([sys.executable, "-m", "socialnav.cli", "metrics", str(path), "--format", fmt],
                          capture_output=True, text=True, timeout=120,
                          env=subprocess_env())
    assert proc.returncode == 2 and "Traceback" not in proc.stderr and str(path) in proc.stderr
