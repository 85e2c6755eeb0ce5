"""Where a policy's jerk (M_IV) and navigation time come from, measured on stored trajectories.

For every successful multi-human episode of one or more result directories (``socialnav evaluate``
keeps trajectories by default) it reports, per policy:

- M_IV (mean squared jerk, (m/s³)²) as the metric computes it;
- the mean |Δv| between consecutive robot velocities [m/s] and its split into a speed part
  (| |v_k+1| − |v_k| |) and a heading part (|v_k+1|·|Δθ| where both speeds > 0.05 m/s);
- the share of steps whose heading changes by more than 10° and whose speed changes by more than
  0.1 m/s;
- the mean speed while moving and the path length over the straight-line distance (detour ratio),
  which together explain navigation time.

    PYTHONPATH=src python benchmarks/analysis/motion_decomposition.py runs/evaluate/wang2022-orca \
        runs/evaluate/wang2022-rgl-s0 [--json]

The last line printed is one JSON object (one entry per result directory).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from socialnav.metrics import score_episode
from socialnav.trajectory import read_trajectories

M4_KEY = "m4_jerk.mean_sq"


def episode_motion(traj) -> dict[str, float]:
    pos = np.asarray(traj.positions)[:, 0]  # robot: agent 0, main samples (no continuation)
    dt = float(traj.dt)
    v = np.diff(pos, axis=0) / dt
    speed = np.linalg.norm(v, axis=1)
    dv = np.linalg.norm(np.diff(v, axis=0), axis=1)
    ds = np.abs(np.diff(speed))
    heading = np.arctan2(v[:, 1], v[:, 0])
    dth = np.abs((np.diff(heading) + np.pi) % (2 * np.pi) - np.pi)
    moving = (speed[:-1] > 0.05) & (speed[1:] > 0.05)
    turn = np.where(moving, speed[1:] * dth, 0.0)
    start, goal = pos[0], np.asarray(traj.goals)[0]
    length = float(np.sum(np.linalg.norm(np.diff(pos, axis=0), axis=1)))
    straight = float(np.linalg.norm(goal - start))
    return {
        "mean_abs_dv": float(dv.mean()) if dv.size else np.nan,
        "mean_speed_change": float(ds.mean()) if ds.size else np.nan,
        "mean_heading_change_term": float(turn.mean()) if turn.size else np.nan,
        "share_turns_over_10deg": float(np.mean(moving & (dth > np.radians(10)))) if dth.size else np.nan,
        "share_speed_changes_over_0.1": float(np.mean(ds > 0.1)) if ds.size else np.nan,
        "mean_moving_speed": float(speed[speed > 0.05].mean()) if np.any(speed > 0.05) else np.nan,
        "detour_ratio": length / straight if straight > 0 else np.nan,
    }


def successful_multi_human(results_dir: Path, visibility: str = "invisible"):
    """The stored trajectories of a result directory's successful multi-human episodes (Table II's)."""
    for path in sorted((results_dir / "trajectories").glob(f"*__{visibility}/*.parquet")):
        if path.parent.name.split("__")[0] in ("passing", "overtaking", "crossing"):
            continue
        yield from (traj for traj in read_trajectories(path) if traj.outcome == "success")


def summarise(results_dir: Path, visibility: str = "invisible") -> dict[str, float]:
    rows = []
    for traj in successful_multi_human(results_dir, visibility):
        row = episode_motion(traj)
        scores = score_episode(traj)
        row[M4_KEY] = float(scores[M4_KEY])
        row["navigation_time"] = float(scores["navigation_time"])
        rows.append(row)
    if not rows:
        raise SystemExit(f"{results_dir}: no successful multi-human episode with a stored trajectory")
    keys = rows[0].keys()
    return {"episodes": len(rows), **{k: float(np.nanmean([r[k] for r in rows])) for k in keys}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", nargs="+", type=Path)
    args = ap.parse_args()
    out = {}
    for d in args.results:
        out[d.name] = summarise(d)
        print(d.name, {k: round(v, 4) for k, v in out[d.name].items()})
    print(json.dumps(out))


if __name__ == "__main__":
    main()
