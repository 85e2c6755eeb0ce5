"""PPO training speed of crowdnav_pp: environment steps per second end to end (collection + updates).

Runs the project's PPO trainer (train/ppo/algorithm.py) under ``wang2022`` for a few updates of the default
schedule (``--config``, default the shipped ``ppo``) and of the same schedule with the CrowdNav++
repository's layer sizes, and, as the reference measured in the same run, the batched world alone
stepping the same environments with constant actions (the collection floor: no network at all).
Validation is left out of the timing (it runs every 50 updates in a real run). The last output line is
one JSON object with:

    env_steps_per_s            default schedule, end to end (goal: >= 5000 on 2 cores)
    collect_share, update_share  its shares of the time (collection: acting + stepping the worlds;
                               update: GAE + the epochs of minibatch steps)
    env_steps_per_s_repo_sizes the same with the repository's layer sizes (attention width 512)
    world_only_env_steps_per_s the reference; ratio_to_world_only = env_steps_per_s / it
    budget_env_steps, budget_hours  the default schedule's budget and its wall time at the measured rate
    threads, load_average_1min  torch threads, and the machine's load when measured (shared machines)

    PYTHONPATH=src python benchmarks/bench_ppo_trainer.py [--threads 1] [--updates 4]

``--preset francis2023`` measures the same under the scenarios with walls, where the network also reads
16 obstacle points per environment (docs/ppo.md, "Among walls"); ``--policy ppo_mlp`` the MLP baseline.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import shutil
import sys
import tempfile
import time

import numpy as np

from socialnav.presets import load_preset
from socialnav.train.ppo.algorithm import train_ppo
from socialnav.train.ppo.settings import NetworkSettings, load_ppo_settings
from socialnav.train.worlds import MultiWorld, mix_human_slots

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _machine import add_record_arguments, cpu_model, emit, run_record  # noqa: E402  (benchmarks/ is not a package)


def measure(settings, updates: int, preset: str) -> dict:
    s = dataclasses.replace(
        settings, total_env_steps=settings.batch_steps * updates, validate_every=10**9, checkpoint_every=10**9
    )
    out = tempfile.mkdtemp(prefix="bench_ppo_")
    try:
        r = train_ppo(preset, out, s, progress=False, log=lambda _: None)
    finally:
        shutil.rmtree(out, ignore_errors=True)
    total = r.collect_time + r.update_time
    return {
        "env_steps": r.env_steps,
        "env_steps_per_s": r.env_steps / total,
        "collect_s": r.collect_time,
        "update_s": r.update_time,
        "collect_share": r.collect_time / total,
        "update_share": r.update_time / total,
    }


def world_only(n_envs: int, steps: int, preset_name: str) -> float:
    preset = load_preset(preset_name)
    world = MultiWorld(preset, mix_human_slots(preset, preset.training.n_humans), n_envs, "train", 5_000_000)
    try:
        world.reset()
        actions = np.tile([0.0, 1.0], (world.batch_size, 1))
        t = time.perf_counter()
        for _ in range(steps):
            for w, lo, hi in zip(world.worlds, world.offsets[:-1], world.offsets[1:], strict=True):
                w.step(actions[lo:hi], final_observation=True, observe=True)
        return world.batch_size * steps / (time.perf_counter() - t)
    finally:
        world.close()




def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", default="ppo", help="PPO config (default: the shipped default schedule)")
    ap.add_argument("--updates", type=int, default=4, help="updates timed per configuration")
    ap.add_argument("--threads", type=int, default=1, help="torch threads (1: best on a shared 2-core VM)")
    ap.add_argument("--skip-repo-sizes", action="store_true")
    ap.add_argument("--device", default="cpu", help="where the network runs: cpu, cuda or auto (world: CPU)")
    ap.add_argument("--preset", default="wang2022", help="the preset trained under (francis2023: walls)")
    ap.add_argument("--policy", default=None, help="the PPO policy (default: the config's, crowdnav_pp)")
    add_record_arguments(ap, "bench_ppo_trainer")
    args = ap.parse_args()
    load = os.getloadavg()[0]
    settings = dataclasses.replace(load_ppo_settings(args.config), threads=args.threads, device=args.device)
    if args.policy:
        settings = dataclasses.replace(settings, policy=args.policy)
    default = measure(settings, args.updates, args.preset)
    print(
        f"default schedule ({settings.n_envs} envs x {settings.rollout_steps} steps): {default}", flush=True
    )
    repo = None
    if not args.skip_repo_sizes:
        repo = measure(
            dataclasses.replace(settings, network=NetworkSettings()), max(2, args.updates // 2), args.preset
        )
        print(f"repository sizes: {repo}", flush=True)
    reference = world_only(settings.n_envs, 200, args.preset)
    print(f"world only: {reference:.0f} env steps/s", flush=True)
    rate = default["env_steps_per_s"]
    emit(
        run_record()
        | {
            "benchmark": "ppo_trainer",
            "policy": settings.policy,
            "preset": args.preset,
            "config": args.config,
            "n_envs": settings.n_envs,
            "rollout_steps": settings.rollout_steps,
            "epochs": settings.epochs,
            "minibatches": settings.minibatches,
            "network": dataclasses.asdict(settings.network),
            "env_steps_per_s": round(rate, 1),
            "goal_env_steps_per_s": 5000,
            "collect_share": round(default["collect_share"], 3),
            "update_share": round(default["update_share"], 3),
            "env_steps_per_s_repo_sizes": None if repo is None else round(repo["env_steps_per_s"], 1),
            "repo_sizes_collect_share": None if repo is None else round(repo["collect_share"], 3),
            "world_only_env_steps_per_s": round(reference, 1),
            "ratio_to_world_only": round(rate / reference, 4),
            "budget_env_steps": settings.total_env_steps,
            "budget_hours": round(settings.total_env_steps / rate / 3600, 2),
            "paper_budget_env_steps": 20_000_000,
            "paper_budget_hours": round(2e7 / rate / 3600, 2),
            "threads": args.threads,
            "device": args.device,
            "load_average_1min": round(load, 2),
            "load_average_1min_after": round(os.getloadavg()[0], 2),
            "cpu": cpu_model(),
            "cpu_count": os.cpu_count(),
        },
        args,
    )


if __name__ == "__main__":
    main()
