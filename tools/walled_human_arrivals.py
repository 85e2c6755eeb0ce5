"""How many humans of the walled scenarios reach their goal (docs/routes.md, "Do the crowds find their way").

Two measurements per scenario of a preset (francis2023 by default) and per human model (ORCA and social
force by default), over the protocol's test episodes:

- **crowd**: the humans alone. Each episode is generated as the protocol generates it, the robot is then
  moved 1 km away with its goal where it stands, so that it succeeds at the first step and the humans walk
  on (the M_III continuation) until every one arrived or the preset's continuation cap (100 s). A human
  reached its goal when its centre came within its radius of it. This is what the routes are for: a
  person who cannot find the door shows here, whatever a robot does.
- **with_robot** (``--robot POLICY``, default ``orca_route``): the protocol's visible pass with that robot
  (the pass with the continuation); "all" counts every human, "uncensored" only the humans of episodes
  that ran to the cap (the robot reached its goal), since an episode that ends in a collision or a timeout
  stops its humans before they could arrive. ``--robot none`` skips it.

Arrival is the ``human_arrival`` metric's rule (the centre within the human's radius of its goal).

    python tools/walled_human_arrivals.py [--episodes 500] [--models orca social_force] [--robot orca_route]
        [--routes shortest|none]

Prints one line per scenario and model, then one JSON object last.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import tempfile
from pathlib import Path

import numpy as np

from socialnav.metrics.progress import human_arrivals, humans_had_full_time
from socialnav.presets import Preset, load_preset
from socialnav.scenarios import make_scenario
from socialnav.sim import World
from socialnav.trajectory import Trajectory

FAR = 1000.0  # [m] where the robot is put for the crowd measurement


def count(trajectories: list[Trajectory], uncensored_only: bool = False) -> dict[str, float | int | None]:
    """{humans, reached_goal, fraction} over the trajectories' humans, as the ``human_arrival`` metric
    counts them (socialnav.metrics.progress); ``uncensored_only``: the episodes whose humans had the
    whole time to arrive."""
    total = hits = 0
    for tr in trajectories:
        if uncensored_only and not humans_had_full_time(tr):
            continue
        humans, reached = human_arrivals(tr)
        total += humans
        hits += reached
    return {"humans": total, "reached_goal": hits, "fraction": round(hits / total, 4) if total else None}


def crowd_alone(preset: Preset, scenario_name: str, episodes: int) -> list[Trajectory]:
    """The scenario's first `episodes` test episodes with the robot moved away: the humans' trajectories."""
    world_settings = dataclasses.replace(preset.world, continue_after_success=True,
                                         continuation_cap=preset.evaluation.continuation_cap)
    n_humans = preset.evaluation.n_humans
    try:
        scenario = make_scenario(scenario_name, n_humans=n_humans)
    except (TypeError, ValueError):  # a scenario whose design fixes its crowd
        scenario = make_scenario(scenario_name)
    out: list[Trajectory] = []
    with World(world_settings, scenario, episodes, split=preset.evaluation.split, count=episodes) as world:
        world.reset()
        world.position[:, 0] = FAR
        world.goal[:, 0] = FAR
        world.velocity[:, 0] = 0.0
        actions = np.zeros((episodes, 2))
        while world.busy:
            out += world.step(actions).finished
    return out


def with_robot(preset: Preset, scenario_name: str, episodes: int, policy: str,
               root: Path) -> list[Trajectory]:
    """The protocol's visible pass of one scenario with a robot policy: its stored trajectories."""
    from socialnav.evaluate import run_protocol
    from socialnav.policies.building import build_policy
    from socialnav.trajectory_io import read_trajectories

    run_dir = root / scenario_name
    run_protocol(build_policy(policy, preset), preset, run_dir, scenarios=[scenario_name], episodes=episodes,
                 visibility="visible", progress=False)
    paths = sorted(run_dir.glob("trajectories/**/*.parquet"))
    return [tr for path in paths for tr in read_trajectories(path)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--preset", default="francis2023", help="a preset with walls (default francis2023)")
    ap.add_argument("--episodes", type=int, default=500, help="test episodes per scenario (default 500)")
    ap.add_argument("--models", nargs="+", default=["orca", "social_force"], help="human models")
    ap.add_argument("--robot", default="orca_route", help="robot policy of the with_robot figures, or none")
    ap.add_argument("--scenarios", nargs="+", help="default: the preset's")
    ap.add_argument("--routes", choices=["shortest", "none"],
                    help="the humans' routes (default: the preset's)")
    args = ap.parse_args()
    base = load_preset(args.preset)
    if args.routes:
        base = dataclasses.replace(base, world=dataclasses.replace(base.world, human_routes=args.routes))
    result: dict = {"preset": base.name, "episodes": args.episodes, "human_routes": base.world.human_routes,
                    "robot": args.robot, "models": {}}
    with tempfile.TemporaryDirectory() as tmp:
        for model in args.models:
            preset = dataclasses.replace(base, world=dataclasses.replace(base.world, human_model=model))
            rows: dict = {}
            result["models"][model] = {"scenarios": rows}
            for scenario in args.scenarios or preset.evaluation.multi_human:
                row = rows[scenario] = {"crowd": count(crowd_alone(preset, scenario, args.episodes))}
                line = f"{model} {scenario}: crowd {row['crowd']['fraction']}"
                if args.robot != "none":
                    trs = with_robot(preset, scenario, args.episodes, args.robot, Path(tmp) / model)
                    row["with_robot"] = {"all": count(trs), "uncensored": count(trs, uncensored_only=True)}
                    line += (f"; with {args.robot}: all {row['with_robot']['all']['fraction']}, uncensored "
                             f"{row['with_robot']['uncensored']['fraction']}")
                print(line, flush=True)
            crowd = [r["crowd"]["fraction"] for r in rows.values() if r["crowd"]["fraction"] is not None]
            result["models"][model]["min_crowd_fraction"] = min(crowd) if crowd else None
    print(json.dumps(result))


if __name__ == "__main__":
    main()
