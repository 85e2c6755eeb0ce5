"""Training speed: RL episodes per second and wall time to the quality bar.

Trains SARL under a preset (default ``wang2022``) with the default training settings (or a
``--config`` YAML and the overrides below) until the validation success reaches ``--target``
(default 0.93) or ``--max-minutes`` run out, and times one gradient step of the replay ratio in
isolation. The last output line is one JSON object with (among others):

    episodes_per_s          RL episodes collected per second of RL wall time (gradient steps and
                            validations included)
    seconds_to_quality      wall time from the start (imitation included) to the first validation
                            at or above the target; null when not reached within the budget
    seconds_per_gradient_step  one Adam step of batch ``rl.batch_size`` (isolated micro-benchmark)

    PYTHONPATH=src python benchmarks/bench_train.py --max-minutes 30
    PYTHONPATH=src python benchmarks/bench_train.py --gradient-steps-per-episode 2 \
        --rl-episodes 2000 --max-minutes 10
    PYTHONPATH=src python benchmarks/bench_train.py --host-overhead-only --threads 1 [--compile]

``host_overhead_ms_per_gradient_step`` (issue #13, goal 0.5 ms) is the time of the same gradient step
with every hidden layer one unit wide: every operation, dispatch, replay sampling and state transform
is still done, next to none of the arithmetic; ``host_overhead_fraction`` is its share of the real step.
``--host-overhead-only`` measures the step both ways in one run, eager (the default training path) and
with the loss compiled (``compile: true`` / ``socialnav train --compile``): keys ``eager`` and
``compiled``; the top-level keys are those of the path ``--compile`` selects (default: eager). A
training run with ``--compile`` trains with the compiled loss and times its step compiled.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import math
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

import torch

from socialnav.policies.learned import ValuePolicy, build
from socialnav.train.optim import AdamSteps, make_optimizer
from socialnav.train.run_directory import resolve_device
from socialnav.train.value.fused_step import FusedTDStep
from socialnav.train.value.memory import ReplayMemory
from socialnav.train.value.rl import replay_td_loss
from socialnav.train.value.settings import load_train_settings
from socialnav.train.value.trainer import train

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _machine import add_record_arguments, emit, run_record  # noqa: E402  (benchmarks/ is not a package)

#: Every hidden layer 1 unit wide: the same operations as the real network with next to no arithmetic.
_NO_ARITHMETIC: dict[str, dict] = {
    "sarl": {
        "mlp1_dims": (1, 1),
        "mlp2_dims": (1, 1),
        "attention_dims": (1, 1, 1),
        "mlp3_dims": (1, 1, 1, 1),
    },
    "om_sarl": {
        "mlp1_dims": (1, 1),
        "mlp2_dims": (1, 1),
        "attention_dims": (1, 1, 1),
        "mlp3_dims": (1, 1, 1, 1),
    },
    "cadrl": {"mlp_dims": (1, 1, 1, 1)},
    "rgl": {"robot_dims": (1, 1), "human_dims": (1, 1), "value_dims": (1, 1, 1, 1)},
}


def time_gradient_step(
    policy_name: str,
    batch_size: int,
    n_humans: int = 5,
    steps: int = 200,
    repeats: int = 1,
    network_kwargs: dict | None = None,
    compiled: bool = False,
    device: str = "cpu",
) -> float:
    """Seconds per TD gradient step, the trainer's own (sample, gather, transform, target forward,
    forward, the divergence check, backward, fused Adam through AdamSteps); the best of ``repeats``
    timings of ``steps`` steps. ``network_kwargs`` changes the layer sizes; ``compiled`` compiles as
    ``compile: true`` does — the whole step as one graph (train/value/fused_step.py) where the network
    traces into one, else the loss — with the compilation outside the timing. Every step's loss is
    read and checked here (the trainer checks a fused step's losses once per burst of steps)."""
    kw = network_kwargs or {}
    dev = torch.device(device)
    net, target = build(policy_name, **kw).to(dev), build(policy_name, **kw).to(dev)
    target.eval().requires_grad_(False)
    policy = ValuePolicy(net, device=dev)
    optimizer = make_optimizer(net.parameters(), 1e-3, dev)
    adam = AdamSteps(optimizer)
    mem = ReplayMemory(10_000, n_humans, device=dev)
    g = torch.Generator().manual_seed(0)
    k = 10_000
    robot = torch.rand(k, 9, generator=g) * 8 - 4
    robot[:, 4], robot[:, 7] = 0.3, 1.0
    humans = torch.rand(k, n_humans, 5, generator=g) * 8 - 4
    humans[..., 4] = 0.3
    mask = torch.ones(k, n_humans, dtype=torch.bool)
    mem.push(robot, humans, mask, torch.zeros(k), robot, humans, mask, torch.zeros(k, dtype=torch.bool))
    fused = FusedTDStep.build(policy, target, mem, optimizer, 0.9, 0.25, batch_size)[0] if compiled else None
    loss_at = replay_td_loss(policy, target, mem, 0.9, 0.25, compiled=compiled and fused is None)
    net.train()

    def step() -> None:
        idx = mem.sample_indices(batch_size, g)
        loss = fused(idx) if fused is not None else loss_at(idx)  # the fused step also updates
        if not math.isfinite(float(loss.detach())):  # the trainer checks every loss
            raise RuntimeError("the benchmark's loss diverged")
        if fused is None:
            adam.zero_grad()
            loss.backward()
            adam.step()

    for _ in range(20):
        step()
    best = math.inf
    for _ in range(repeats):
        t = time.perf_counter()
        for _ in range(steps):
            step()
        best = min(best, (time.perf_counter() - t) / steps)
    return best


def host_overhead(
    policy_name: str, batch_size: int, repeats: int = 3, compiled: bool = False, device: str = "cpu"
) -> dict[str, float]:
    """Host overhead of one gradient step: the same step with the network's arithmetic removed (every
    hidden layer one unit wide: the same operations, dispatches, sampling and state transforms, next
    to no FLOPs), measured against the real step in the same run (issue #13)."""
    if policy_name not in _NO_ARITHMETIC:
        raise SystemExit(f"--host-overhead knows {', '.join(_NO_ARITHMETIC)}, not {policy_name!r}")
    full = time_gradient_step(
        policy_name, batch_size, steps=300, repeats=repeats, compiled=compiled, device=device
    )
    bare = time_gradient_step(
        policy_name,
        batch_size,
        steps=300,
        repeats=repeats,
        network_kwargs=_NO_ARITHMETIC[policy_name],
        compiled=compiled,
        device=device,
    )
    return {
        "ms_per_gradient_step": full * 1e3,
        "gradient_steps_per_s": 1.0 / full,
        "host_overhead_ms_per_gradient_step": bare * 1e3,
        "host_overhead_fraction": bare / full,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--policy", default="sarl")
    ap.add_argument("--preset", default="wang2022")
    ap.add_argument("--config", help="training settings YAML (default: the shipped defaults)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--target", type=float, default=0.93, help="validation success that counts as the bar")
    ap.add_argument("--max-minutes", type=float, default=30.0)
    ap.add_argument("--gradient-steps-per-episode", type=float)
    ap.add_argument("--batch-size", type=int, help="RL minibatch")
    ap.add_argument("--collection-batch", type=int)
    ap.add_argument("--rl-episodes", type=int)
    ap.add_argument("--validate-every", type=int)
    ap.add_argument("--il-episodes", type=int)
    ap.add_argument("--il-epochs", type=int)
    ap.add_argument("--threads", type=int)
    ap.add_argument("--device", help="cpu, cuda or auto (default: the settings' device, cpu)")
    ap.add_argument("--out", help="run directory (default: a temporary one, removed afterwards)")
    ap.add_argument("--progress", action="store_true")
    ap.add_argument("--skip-step-timing", action="store_true",
                    help="after training, do not time a gradient step in isolation (saves its compilations)")
    ap.add_argument("--compile", action="store_true", help="compile the RL loss (compile: true)")
    ap.add_argument(
        "--host-overhead-only",
        action="store_true",
        help="only time a gradient step with and without the network's arithmetic (no training run)",
    )
    add_record_arguments(ap, "bench_train")
    args = ap.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    batch = args.batch_size or 100
    dev = str(resolve_device(args.device or "cpu"))
    if args.host_overhead_only:
        modes = {
            mode: {
                k: round(v, 4)
                for k, v in host_overhead(args.policy, batch, compiled=compiled, device=dev).items()
            }
            for mode, compiled in (("eager", False), ("compiled", True))
        }
        chosen = "compiled" if args.compile else "eager"
        report = {
            "benchmark": "train_step",
            "policy": args.policy,
            "batch_size": batch,
            "threads": torch.get_num_threads(),
            "cpu_count": os.cpu_count(),
            "mode": chosen,
            "device": dev,
            **modes[chosen],
            "host_overhead_goal_ms": 0.5,
            **modes,
            "compiled_speedup": round(modes["eager"]["ms_per_gradient_step"]
                                      / modes["compiled"]["ms_per_gradient_step"], 3),
        }
        for mode, m in modes.items():
            print(
                f"{args.policy} ({mode}): {m['ms_per_gradient_step']:.3f} ms per gradient step "
                f"({m['gradient_steps_per_s']:.0f}/s), {m['host_overhead_ms_per_gradient_step']:.3f} ms "
                "of it without the arithmetic (goal <= 0.5 ms)"
            )
        emit(run_record() | report, args)
        return

    s = load_train_settings(
        args.config, seed=args.seed, threads=args.threads, collection_batch=args.collection_batch,
        device=args.device,
    )
    rl_over = {
        k: v
        for k, v in {
            "gradient_steps_per_episode": args.gradient_steps_per_episode,
            "batch_size": args.batch_size,
            "episodes": args.rl_episodes,
            "validate_every": args.validate_every,
        }.items()
        if v is not None
    }
    il_over = {
        k: v for k, v in {"episodes": args.il_episodes, "epochs": args.il_epochs}.items() if v is not None
    }
    s = dataclasses.replace(
        s,
        compile=s.compile or args.compile,
        rl=dataclasses.replace(s.rl, **rl_over),
        imitation=dataclasses.replace(s.imitation, **il_over),
    )
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="bench_train_"))
    budget = args.max_minutes * 60.0
    reached: dict = {}
    history: list = []

    def on_validation(episode: int, val: dict, wall: float) -> bool:
        history.append(
            {
                "episode": episode,
                "success": val["success"],
                "collision": val["collision"],
                "wall_time": round(wall, 1),
            }
        )
        if val["success"] >= args.target and not reached:
            reached.update(episode=episode, wall_time=wall, success=val["success"])
        return bool(reached) or wall >= budget

    t0 = time.perf_counter()
    result = train(
        args.policy,
        args.preset,
        out,
        s,
        progress=args.progress,
        on_validation=on_validation,
        log=lambda line: print(line, flush=True),
    )
    total = time.perf_counter() - t0
    with open(out / "curves.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    il_wall = float(rows[0]["wall_time"]) if rows and rows[0]["phase"] == "il" else 0.0
    rl_rows = [r for r in rows if r["phase"] == "rl"]
    rl_eps = int(rl_rows[-1]["episode"]) if rl_rows else 0
    rl_wall = (float(rl_rows[-1]["wall_time"]) - il_wall) if rl_rows else 0.0
    # From the first RL log row on: without the one-time costs before it (a compiled step's build)
    steady = None
    if len(rl_rows) >= 2 and float(rl_rows[-1]["wall_time"]) > float(rl_rows[0]["wall_time"]):
        steady = (int(rl_rows[-1]["episode"]) - int(rl_rows[0]["episode"])) / (
            float(rl_rows[-1]["wall_time"]) - float(rl_rows[0]["wall_time"])
        )
    sec_step = math.nan
    if not args.skip_step_timing:
        sec_step = time_gradient_step(args.policy, s.rl.batch_size, compiled=s.compile, device=dev)
    overhead = {}
    if args.policy in _NO_ARITHMETIC and not args.skip_step_timing:
        overhead = host_overhead(args.policy, s.rl.batch_size, compiled=s.compile, device=dev)
    report = {
        "benchmark": "train",
        "policy": args.policy,
        "preset": args.preset,
        "seed": args.seed,
        "threads": torch.get_num_threads(),
        "cpu_count": os.cpu_count(),
        "compile": s.compile,
        "device": dev,
        "gradient_steps_per_episode": s.rl.gradient_steps_per_episode,
        "batch_size": s.rl.batch_size,
        "collection_batch": s.collection_batch,
        "il_episodes": s.imitation.episodes,
        "il_epochs": s.imitation.epochs,
        "imitation_seconds": round(il_wall, 1),
        "rl_episodes": rl_eps,
        "rl_seconds": round(rl_wall, 1),
        "gradient_steps": result.gradient_steps,
        "episodes_per_s": round(rl_eps / rl_wall, 3) if rl_wall > 0 else None,
        "episodes_per_s_steady": round(steady, 3) if steady else None,
        "seconds_per_gradient_step": None if math.isnan(sec_step) else round(sec_step, 5),
        **{k: round(v, 4) for k, v in overhead.items()},
        "seconds_to_quality": round(reached["wall_time"], 1) if reached else None,
        "episode_at_quality": reached.get("episode"),
        "target": args.target,
        "best_val": {
            k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in result.best_val.items()
        },
        "validations": history,
        "wall_seconds": round(total, 1),
        "out": str(out) if args.out else None,
    }
    if not args.out:
        shutil.rmtree(out, ignore_errors=True)
    emit(run_record() | report, args)


if __name__ == "__main__":
    main()
