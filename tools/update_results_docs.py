"""Rewrites the figures the README and the results log show from the committed result files, so that they
cannot contradict them.

    python tools/update_results_docs.py          # rewrite README.md's blocks, benchmarks/results/README.md
    python tools/update_results_docs.py --check  # exit 1 naming what is stale

- README.md, block `results`: the paper's learned baselines as trained here (seeds 0-2, full wang2022
  protocol: `benchmarks/results/<policy>_wang2022[_sS]_summary.json`), pooled success, navigation time,
  M_I and M_IV as mean ± std over seeds, beside the paper's Table II
  (src/socialnav/configs/paper/wang2022.yaml).
- README.md, block `speed`: world, protocol and training speed, each against its reference.
- benchmarks/results/README.md: every benchmark's current figure, command, date and machine, from
  `benchmarks/results/bench_*.json` (one JSON object per file: the current run), and a link to its
  history, `benchmarks/results/history/<name>.jsonl` (one JSON object per run: date, machine, command,
  result, notes; `benchmarks/_machine.py` appends to it when a benchmark runs with `--record`).

tests/docs/test_results_docs.py runs ``--check``; run this script after committing a new result file.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import statistics
import sys
from collections.abc import Callable
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
README = ROOT / "README.md"
RESULTS_README = RESULTS / "README.md"
HISTORY = RESULTS / "history"
PAPER = ROOT / "src" / "socialnav" / "configs" / "paper" / "wang2022.yaml"

# (policy, label, the paper's Table II row or None)
BASELINES = (
    ("cadrl", "CADRL", "CADRL"),
    ("lstm_rl", "GA3C-CADRL", "GA3C-CADRL"),
    ("sarl", "SARL", None),
    ("om_sarl", "OM-SARL", "OM-SARL"),
    ("rgl", "RGL", "RGL"),
    ("mp_rgl", "MP-RGL", None),
    ("crowdnav_pp", "CrowdNav++ (PPO)", None),
)
# (column, summary key, scale, decimals, the paper's key)
COLUMNS = (
    ("Success %", "success_rate", 100.0, 2, "success"),
    ("Nav. time (s)", "nav_time_s", 1.0, 2, "nav_time"),
    ("M_I (s)", "m1_personal_space.duration_s@eps=0.2,distance=clearance.mean", 1.0, 2, "m1"),
    ("M_IV", "m4_jerk.mean_sq.mean", 1.0, 1, "m4"),
)


def load(name: str) -> dict:
    return json.loads((RESULTS / name).read_text())


# -- README: results ------------------------------------------------------------------------------
def pooled(path: Path) -> dict:
    rows = json.loads(path.read_text())["rows"]
    (row,) = [r for r in rows if r["scenario"] == "pooled" and r["visibility"] == "invisible"]
    return row


def seed_summaries(policy: str) -> list[Path]:
    files = [RESULTS / f"{policy}_wang2022_summary.json"]
    files += sorted(RESULTS.glob(f"{policy}_wang2022_s[0-9]_summary.json"))
    return [f for f in files if f.exists()]


def mean_std(values: list[float], scale: float, decimals: int) -> str:
    values = [v * scale for v in values if v is not None and math.isfinite(v)]
    if not values:
        return "–"
    if len(values) == 1:
        return f"{values[0]:.{decimals}f}"
    return f"{statistics.mean(values):.{decimals}f} ± {statistics.stdev(values):.{decimals}f}"


def results_block() -> str:
    paper = yaml.safe_load(PAPER.read_text())["table2"]
    header = ["Policy", "seeds"] + [f"{c[0]} ours / paper" for c in COLUMNS]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for policy, label, paper_row in BASELINES:
        files = seed_summaries(policy)
        rows = [pooled(f) for f in files]
        cells = [label, str(len(rows))]
        for _, key, scale, decimals, paper_key in COLUMNS:
            ours = mean_std([r.get(key) for r in rows], scale, decimals)
            theirs = paper.get(paper_row, {}).get(paper_key) if paper_row else None
            if isinstance(theirs, list):
                theirs = theirs[0]
            cells.append(f"{ours} / {theirs:.{decimals}f}" if theirs is not None else f"{ours} / –")
        lines.append("| " + " | ".join(cells) + " |")
    lines += [
        "",
        "Mean ± std over training seeds (each seed's pooled result over the four multi-human scenarios, "
        "2,000 test episodes, invisible robot); paper: its Table II (it has no SARL, MP-RGL or "
        "policy-gradient row; CrowdNav++ is the attention-graph policy trained here with PPO, docs/ppo.md). "
        "GA3C-CADRL is `lstm_rl`, an LSTM value network in the spirit of GA3C-CADRL (CrowdNav's LSTM-RL), "
        "trained as the other value-based baselines, not the A3C policy-gradient original "
        "(docs/policies_learned.md). M_IV, the jerk, "
        "is Wang et al.'s forward difference (docs/metrics.md); with central differences five of the six "
        "value-based baselines land in the paper's band and OM-SARL just above it "
        "(docs/reproduction_jerk.md).",
    ]
    return "\n".join(lines)


# -- README: speed --------------------------------------------------------------------------------
def speed_block() -> str:
    world, walls = load("bench_world.json"), load("bench_world_obstacles.json")
    protocol, sarl = load("bench_protocol.json"), load("bench_protocol_sarl.json")
    train, ppo, sb3 = load("bench_train.json"), load("bench_ppo_trainer.json"), load("bench_ppo.json")
    lidar, exec_ = load("bench_world_lidar.json"), load("bench_protocol_exec.json")
    rows = [
        (
            "World: 5 ORCA humans + ORCA robot, B = 4096",
            f"{world['env_steps_per_s'] / 1e6:.2f} M env-steps/s",
            f"**{world['ratio_vs_navground']:.1f}×** navground (RVO2) in the same run; "
            f"{world['speedup_2_threads_vs_1']:.2f}× on 2 threads vs 1",
        ),
        (
            "World among 8 wall segments",
            f"{walls['env_steps_per_s_obstacles'] / 1e3:.0f} k env-steps/s",
            f"**{walls['ratio_vs_navground_obstacles']:.1f}×** navground with the same walls",
        ),
        (
            f"The same walls, a {lidar['lidar_beams']}-beam lidar on the robot",
            f"{lidar['env_steps_per_s_lidar'] / 1e3:.0f} k env-steps/s",
            f"the lidar costs {lidar['lidar_cost']:.2f}× (goal ≤ 1.5); "
            f"**{lidar['lidar_vs_navground']:.1f}×** navground with its lidar "
            f"(goal 8{'' if lidar['lidar_vs_navground'] >= 8 else ', not met'})",
        ),
        (
            "The same walls, humans on routes",
            f"{walls['env_steps_per_s_routed'] / 1e3:.0f} k env-steps/s",
            f"{walls['ratio_routed_vs_unrouted']:.2f} of the speed without routes "
            f"(goal 0.8{'' if walls['ratio_routed_vs_unrouted'] >= 0.8 else ', not met'}; runs hours apart "
            "vary: [routes.md](docs/routes.md#cost))",
        ),
        (
            f"Protocol: full `wang2022`, ORCA robot ({protocol['episodes']:,} episodes, scored, stored)",
            f"{protocol['seconds']:.1f} s",
            f"storing trajectories costs {protocol['trajectory_time_ratio']:.2f}× the run without them",
        ),
        (
            "Protocol: full `wang2022` through the exec protocol (C++ example planner)",
            f"{exec_['exec_env_steps_per_s']:,.0f} env-steps/s",
            f"{exec_['exec_vs_native']:.2f}× the same decisions in-process (goal 50,000 env-steps/s)",
        ),
        (
            f"Protocol: full `wang2022`, shipped SARL ({sarl['episodes']:,} episodes)",
            f"{sarl['seconds']:.1f} s",
            f"goal ≤ {sarl['target_seconds']:.0f} s",
        ),
        (
            "Training: SARL to validation success 0.95 (`wang2022`)",
            f"{train['seconds_to_quality']:.0f} s",
            f"{train['gradient_steps']:,} gradient steps",
        ),
        (
            "Training: PPO, CrowdNav++ attention graph, end to end",
            f"{ppo['env_steps_per_s']:,.0f} env-steps/s",
            f"the bare world {ppo['world_only_env_steps_per_s'] / 1e3:,.0f} k env-steps/s (updates dominate)",
        ),
        (
            "Training: SB3 PPO rollouts on the native vector env (64 envs)",
            f"{sb3['sb3_adapter_env_steps_per_s']:,.0f} env-steps/s",
            f"**{sb3['sb3_adapter_speedup_vs_subproc']:.0f}×** SB3's `SubprocVecEnv`",
        ),
    ]
    lines = ["| what | figure | against the reference |", "|---|---|---|"]
    lines += [f"| {a} | {b} | {c} |" for a, b, c in rows]
    lines += [
        "",
        "2-core x86-64 VMs (AMD EPYC with AVX-512 where the run recorded its CPU model), figures from "
        "`benchmarks/results/*.json`; every benchmark, "
        "its command, date and machine: [benchmarks/results/README.md](benchmarks/results/README.md).",
    ]
    return "\n".join(lines)


# -- the results log ------------------------------------------------------------------------------
def _f(value, fmt: str = ",.0f") -> str:
    return "–" if value is None else format(value, fmt)


#: file -> (what it measures, default command, current figure)
LOG: dict[str, tuple[str, str, Callable[[dict], str]]] = {
    "bench_world.json": (
        "batched world, 5 ORCA humans + ORCA robot",
        "python benchmarks/bench_world.py",
        lambda d: (
            f"{_f(d['env_steps_per_s'])} env-steps/s at B = {d['batch']}, "
            f"{d['ratio_vs_navground']:.2f}× navground, {d['speedup_2_threads_vs_1']}× "
            "2 vs 1 threads"
        ),
    ),
    "bench_world_obstacles.json": (
        "the world among 8 radial walls",
        "python benchmarks/bench_world.py --obstacles",
        lambda d: (
            f"{_f(d['env_steps_per_s_obstacles'])} env-steps/s, "
            f"{d['ratio_vs_navground_obstacles']}× navground, "
            f"{d['ratio_vs_open_world']} of the open floor"
            f"; routed/unrouted {d['ratio_routed_vs_unrouted']} (goal >= 0.8, interleaved)"
        ),
    ),
    "bench_world_lidar.json": (
        "the walled world with a 360-beam lidar on the robot",
        "python benchmarks/bench_world.py --obstacles --lidar 360",
        lambda d: (
            f"{_f(d['env_steps_per_s_lidar'])} env-steps/s; lidar_cost {d['lidar_cost']} (goal <= 1.5), "
            f"lidar_vs_navground {d['lidar_vs_navground']} (goal >= 8)"
        ),
    ),
    "bench_route_graphs.json": (
        "route graphs of office-like grid maps, first plan on each",
        "python benchmarks/bench_route_graphs.py --max-walls 400",
        lambda d: (
            f"{d['graph_ms_100_walls']} ms for 100 wall segments, {d['graph_ms_200_walls']} ms for 200; "
            f"growth exponent {d['growth_exponent']}"
        ),
    ),
    "bench_world_obstacles_1thread.json": (
        "the same on 1 thread",
        "python benchmarks/bench_world.py --obstacles --threads 1",
        lambda d: (
            f"{_f(d['env_steps_per_s_obstacles'])} env-steps/s, "
            f"{d['ratio_vs_navground_obstacles']}× navground"
        ),
    ),
    "bench_world_obstacles_room.json": (
        "the world in a room map",
        "python benchmarks/bench_world.py --obstacles --map room",
        lambda d: (
            f"{_f(d['env_steps_per_s_obstacles'])} env-steps/s, "
            f"{d['ratio_vs_navground_obstacles']}× navground"
        ),
    ),
    "bench_protocol.json": (
        "full wang2022 protocol, ORCA robot",
        "python benchmarks/bench_protocol.py",
        lambda d: (
            f"{d['seconds']} s for {d['episodes']:,} episodes; trajectories {d['trajectory_time_ratio']}×"
        ),
    ),
    "bench_protocol_francis2023.json": (
        "francis2023 protocol (walls), ORCA robot",
        "python benchmarks/bench_protocol.py --preset francis2023",
        lambda d: f"{d['seconds']} s for {d['episodes']:,} episodes (goal {d['target_seconds']} s)",
    ),
    "bench_protocol_exec.json": (
        "full wang2022 protocol through the exec protocol (C++ example planner)",
        "python benchmarks/bench_protocol.py --exec",
        lambda d: (
            f"{_f(d['exec_env_steps_per_s'])} env-steps/s (goal 50,000), exec_vs_native {d['exec_vs_native']}"
        ),
    ),
    "bench_protocol_sarl.json": (
        "full wang2022 protocol, shipped SARL",
        "python benchmarks/bench_protocol.py --policy sarl",
        lambda d: (
            f"{d['seconds']} s for {d['episodes']:,} episodes "
            f"({d['scorer']} scorer; goal {d['target_seconds']} s)"
        ),
    ),
    "bench_policy.json": (
        "batched SARL action selection",
        "python benchmarks/bench_policy.py",
        lambda d: (
            f"{d['fraction_of_matmul_peak']} of the same-window matmul rate at B = "
            f"{d['fraction_batch']} ({d.get('native_kernel')} kernel), "
            f"{_f(d['env_steps_per_s'])} env-steps/s"
        ),
    ),
    "bench_policy_rgl.json": (
        "RGL / MP-RGL decision cost beside SARL",
        "python benchmarks/bench_policy.py",
        lambda d: (
            f"RGL {_f(d['rgl_env_steps_per_s'])} env-steps/s; MP-RGL d2w2 "
            f"{d['mp_rgl_d2w2_ms_per_decision']} ms per decision"
        ),
    ),
    "bench_metrics.json": (
        "scoring 10,000 stored episodes",
        "python benchmarks/bench_metrics.py",
        lambda d: f"{d['seconds']} s ({_f(d['episodes_per_s'])} episodes/s, {d['workers']} workers)",
    ),
    "bench_report.json": (
        "HTML report of a full run",
        "python benchmarks/bench_report.py",
        lambda d: f"{d['seconds']} s, {d['report_mb']} MB",
    ),
    "bench_reproduce.json": (
        "evaluation half of socialnav reproduce",
        "python benchmarks/bench_reproduce.py",
        lambda d: (
            f"{d['seconds']} s for {len(d['learned_policies'])} learned checkpoints and "
            f"{len(d['per_policy_seconds']) - len(d['learned_policies'])} natives, those shipped "
            f"when it ran (goal {d['goal_seconds']} s)"
        ),
    ),
    "bench_sweep.json": (
        "socialnav sweep, local workers and Ray",
        "python benchmarks/bench_sweep.py",
        lambda d: (
            f"{d['local_speedup_2_vs_1']}× 2 vs 1 workers; Ray overhead "
            f"{100 * d['ray_overhead_fraction']:.1f} %"
        ),
    ),
    "bench_train.json": (
        "SARL training to validation 0.95",
        "python benchmarks/bench_train.py",
        lambda d: f"{d['seconds_to_quality']} s ({d['gradient_steps']:,} gradient steps)",
    ),
    "bench_train_compiled_quality.json": (
        "the same with --compile",
        "(see the file's command)",
        lambda d: f"{d.get('seconds_to_quality', d.get('rl_seconds'))} s",
    ),
    "bench_train_host_overhead.json": (
        "host overhead per gradient step, eager",
        "(see the file's command)",
        lambda d: "per-run values in the file",
    ),
    "bench_train_host_overhead_compiled.json": (
        "host overhead, compiled loss",
        "(see the file's command)",
        lambda d: "per-run values in the file",
    ),
    "bench_train_host_overhead_fused.json": (
        "host overhead, fused compiled step",
        "(see the file's command)",
        lambda d: "per-run values in the file",
    ),
    "bench_train_ratio100_compiled.json": (
        "100 gradient steps per episode, compiled loss",
        "(see the file's command)",
        lambda d: f"RL {d['rl_speedup_compiled_vs_eager']}× eager",
    ),
    "bench_train_ratio100_fused.json": (
        "100 gradient steps per episode, fused step",
        "(see the file's command)",
        lambda d: f"RL {d['rl_speedup_compiled_vs_eager']}× eager",
    ),
    "bench_ppo_trainer.json": (
        "PPO trainer end to end (crowdnav_pp)",
        "python benchmarks/bench_ppo_trainer.py",
        lambda d: f"{_f(d['env_steps_per_s'])} env-steps/s ({d['threads']} thread, {d['device']})",
    ),
    "bench_ppo_trainer_francis2023.json": (
        "PPO trainer among walls (crowdnav_pp, francis2023)",
        "python benchmarks/bench_ppo_trainer.py --skip-repo-sizes --updates 6 --preset francis2023",
        lambda d: f"{_f(d['env_steps_per_s'])} env-steps/s ({d['threads']} thread, {d['device']})",
    ),
    "bench_ppo.json": (
        "SB3 PPO on the native vector env",
        "python benchmarks/bench_ppo.py",
        lambda d: (
            f"rollouts {d['sb3_adapter_speedup_vs_subproc']}× SubprocVecEnv, "
            f"{d['sb3_adapter_speedup_vs_dummy']}× DummyVecEnv"
        ),
    ),
}


HISTORY_KEYS = ("date", "machine", "command", "result", "notes")


def load_history(path: Path) -> list[dict]:
    """The runs of one history file (JSON lines); a malformed line stops the script naming it."""
    runs = []
    for number, line in enumerate(path.read_text().splitlines(), 1):
        if not line.strip():
            continue
        where = f"{path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}:{number}"
        try:
            run = json.loads(line)
        except json.JSONDecodeError as err:
            raise SystemExit(f"{where}: not a JSON object ({err.msg})") from None
        if not isinstance(run, dict):
            raise SystemExit(f"{where}: not a JSON object")
        missing = [k for k in HISTORY_KEYS if k not in run]
        if missing:
            raise SystemExit(f"{where}: no {', '.join(missing)} (every run has {', '.join(HISTORY_KEYS)})")
        if not re.fullmatch(r"\d{4}-\d\d-\d\d", str(run["date"])):
            raise SystemExit(f"{where}: date {run['date']!r} is not YYYY-MM-DD")
        runs.append(run)
    return runs


def history_cell(stem: str) -> str:
    path = HISTORY / f"{stem}.jsonl"
    if not path.exists():
        return "–"
    runs = load_history(path)
    if not runs:
        raise SystemExit(f"{path}: no runs (delete the file or record a run)")
    first, last = runs[0]["date"], runs[-1]["date"]
    span = first if first == last else f"{first} – {last}"
    return f"[{len(runs)} run{'s' if len(runs) != 1 else ''}, {span}](history/{stem}.jsonl)"


def results_readme() -> str:
    files = sorted(p.name for p in RESULTS.glob("bench_*.json"))
    unknown = [f for f in files if f not in LOG]
    if unknown:
        raise SystemExit(f"no entry in tools/update_results_docs.py LOG for {', '.join(unknown)}")
    orphans = sorted(p.name for p in HISTORY.glob("*.jsonl") if f"{p.stem}.json" not in files)
    if orphans:
        raise SystemExit(f"history without a current result file: {', '.join(orphans)} "
                         "(a history belongs to a benchmarks/results/<name>.json)")
    lines = [
        "<!-- generated by tools/update_results_docs.py from the JSON files here: do not edit -->",
        "",
        "# Benchmark results",
        "",
        "The current figure of every benchmark, from its `bench_*.json` file (the run the docs cite), with",
        "the command that produced it, the date and the machine (every benchmark's JSON line starts with",
        "them, `benchmarks/_machine.py`; files written before it did carry the date of their commit and",
        "the CPU model only where the run recorded it). Every earlier run is a line of the benchmark's",
        "history, `history/<name>.jsonl`: one JSON object per run with its `date`, `machine`, `command`,",
        "the benchmark's JSON line as `result`, and `notes` on the conditions it ran under (machine load,",
        "what changed since the run before); runs converted from earlier text logs name the log in",
        "`source` and keep its text output in `output`. A benchmark run with `--record` writes its",
        "`<name>.json` and appends to its history (`--notes` adds the conditions). The raw outputs of the",
        "GPU-machine checks are in `gpu/` (with their own README), training logs in `train_logs/` and",
        "`ppo_logs/`.",
        "",
        "| file | measures | current figure | command | date | machine | history |",
        "|---|---|---|---|---|---|---|",
    ]
    for name in files:
        data = load(name)
        what, command, figure = LOG[name]
        command = data.get("command") if isinstance(data.get("command"), str) else command
        lines.append(
            f"| `{name}` | {what} | {figure(data)} | `{command.replace('|', '/')}` | "
            f"{data.get('date', '–')} | {data.get('machine', '–')} | {history_cell(name[:-5])} |"
        )
    lines += [
        "",
        "Training and evaluation results of the baselines (`<policy>_wang2022[_sS]_summary.json`, Table",
        "II/III markdown beside them, training curves and configs) are described in `docs/reproduction.md`.",
    ]
    return "\n".join(lines) + "\n"


# -- rewriting ------------------------------------------------------------------------------------
BLOCKS: dict[str, Callable[[], str]] = {"results": results_block, "speed": speed_block}


def rewrite_readme(text: str) -> str:
    for name, build in BLOCKS.items():
        pattern = re.compile(
            rf"(<!-- BEGIN generated: {name} .*?-->\n)(.*?)(<!-- END generated: {name} -->)", re.S
        )
        if not pattern.search(text):
            raise SystemExit(f"README.md has no generated block {name!r}")
        text = pattern.sub(lambda m, b=build: m[1] + b() + "\n" + m[3], text)
    return text


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true", help="only report what is stale (exit 1)")
    args = parser.parse_args(argv)
    targets = {README: rewrite_readme(README.read_text()), RESULTS_README: results_readme()}
    stale = [p for p, text in targets.items() if not p.exists() or p.read_text() != text]
    if args.check:
        if stale:
            names = ", ".join(str(p.relative_to(ROOT)) for p in stale)
            print(f"stale: {names}; run python tools/update_results_docs.py", file=sys.stderr)
            return 1
        return 0
    for path in stale:
        path.write_text(targets[path])
    print(f"rewritten: {', '.join(str(p.relative_to(ROOT)) for p in stale) or 'none'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
