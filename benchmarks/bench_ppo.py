"""PPO throughput on socialnav: Stable-Baselines3 on the native vector env (SocialNavVecEnv) vs the same
PPO on SB3's SubprocVecEnv and DummyVecEnv of the single Gymnasium env, in one run.

Every variant trains the same PPO (``MultiInputPolicy``, SB3's default network and hyperparameters
except ``n_steps``) on circle crossing with 5 ORCA humans, ``--envs`` environments, the same
observation (socialnav.sim.learner_obs defaults: float32, world frame). Measured per variant:

- ``env_steps_per_s``: env-steps collected per second of SB3's rollout collection (policy inference,
  stepping, buffer writes: everything the VecEnv choice changes), best of the timed rounds (``_median``
  beside it);
- ``learn_env_steps_per_s``: env-steps per second of a whole round of ``learn()`` (one rollout plus
  its PPO update: 10 epochs of minibatches of 64, which cost the same with every VecEnv and dominate).

A round is one rollout and its update; rounds alternate between the variants and the first of each
(resets, process start-up) is not timed. Every variant's native world runs ``--world-threads``
worker threads (1 by default: a single env holds one episode, and 64 episodes are too few to share).

``sb3_adapter_speedup_vs_subproc`` / ``_vs_dummy`` are ratios of ``env_steps_per_s`` (goal >= 5 vs
SubprocVecEnv, issue #29); ``..._median`` the ratios of the medians, ``sb3_adapter_learn_speedup_...``
those of whole rounds. SubprocVecEnv uses the ``fork`` start method (the children share the
parent's imported modules; ``forkserver`` would import torch in each of the 64 processes).

    python benchmarks/bench_ppo.py [--envs 64] [--n-steps 64] [--rounds 4] [--world-threads 1]
        [--torch-threads 1] [--only sb3_adapter ...]

Prints one line per variant, then one JSON object last. Every key of an SB3 variant starts with
``sb3_``; another trainer (the project's own PPO) adds its own measurement beside ``SB3Run``, run in
the same alternation, under its own key prefix.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import statistics
import sys
import time

import torch

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _machine import add_record_arguments, cpu_model, emit, run_record  # noqa: E402  (benchmarks/ is not a package)

SCENARIO = {"scenario": "circle_crossing", "scenario_params": {"n_humans": 5}}


def _rollout_timer():
    from stable_baselines3.common.callbacks import BaseCallback

    class RolloutTimer(BaseCallback):
        """Seconds of each rollout collection (SB3 calls on_rollout_start/end around it)."""

        def __init__(self):
            super().__init__()
            self.collect: list[float] = []

        def _on_rollout_start(self) -> None:
            self._t0 = time.perf_counter()

        def _on_rollout_end(self) -> None:
            self.collect.append(time.perf_counter() - self._t0)

        def _on_step(self) -> bool:
            return True

    return RolloutTimer()


def _world() -> dict:
    return {"threads": WORLD_THREADS}


def _single_env_factory():
    import gymnasium as gym

    import socialnav  # noqa: F401  (registers the ids)
    from socialnav.envs.learner_wrappers import LearnerObservation

    env = gym.make("socialnav/CircleCrossing-v0", scenario_params=SCENARIO["scenario_params"], world=_world())
    return LearnerObservation(env)


def make_sb3_adapter(n: int):
    from socialnav.integrations.sb3 import SocialNavVecEnv

    return SocialNavVecEnv(
        SCENARIO["scenario"], n, scenario_params=SCENARIO["scenario_params"], world=_world()
    )


def make_sb3_subproc(n: int):
    from stable_baselines3.common.vec_env import SubprocVecEnv

    return SubprocVecEnv([_single_env_factory] * n, start_method="fork")


def make_sb3_dummy(n: int):
    from stable_baselines3.common.vec_env import DummyVecEnv

    return DummyVecEnv([_single_env_factory] * n)


VARIANTS = {
    "sb3_adapter": make_sb3_adapter,
    "sb3_subproc": make_sb3_subproc,
    "sb3_dummy": make_sb3_dummy,
}
WORLD_THREADS = 1


class SB3Run:
    """One PPO model on one VecEnv, trained a rollout (plus its update) at a time."""

    def __init__(self, make_env, envs: int, n_steps: int, seed: int):
        from stable_baselines3 import PPO

        self.venv = make_env(envs)
        self.model = PPO("MultiInputPolicy", self.venv, n_steps=n_steps, seed=seed, device="cpu", verbose=0)
        self.steps = envs * n_steps
        self.timer = _rollout_timer()
        self.rounds: list[tuple[float, float]] = []  # (collection seconds, learn() seconds)

    def round(self) -> None:
        first = not self.timer.collect
        start = time.perf_counter()
        self.model.learn(self.steps, callback=self.timer, reset_num_timesteps=first)
        self.rounds.append((self.timer.collect[-1], time.perf_counter() - start))

    def result(self) -> dict:
        timed = self.rounds[1:]  # the first round (resets, start-up, first allocations) is left out
        collect = [self.steps / c for c, _ in timed]
        learn = [self.steps / t for _, t in timed]
        return {
            "env_steps_per_s": max(collect),
            "env_steps_per_s_median": statistics.median(collect),
            "learn_env_steps_per_s": max(learn),
            "env_steps_per_round": self.steps,
            "rounds_timed": len(timed),
        }




def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--envs", type=int, default=64)
    ap.add_argument("--n-steps", type=int, default=64, help="PPO n_steps (per env and rollout)")
    ap.add_argument(
        "--rounds",
        type=int,
        default=4,
        help="rollouts (each with its PPO update) per variant, alternating; the first is not timed",
    )
    ap.add_argument(
        "--world-threads",
        type=int,
        default=1,
        help="native worker threads of every variant's world (1: a single env has one episode, "
        "and 64 are too few to share)",
    )
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--only", nargs="+", choices=sorted(VARIANTS), help="measure only these variants")
    ap.add_argument(
        "--torch-threads",
        type=int,
        default=1,
        help="PyTorch intra-op threads of the learner (1: the least sensitive to other load)",
    )
    add_record_arguments(ap, "bench_ppo")
    args = ap.parse_args(argv)
    if args.rounds < 2:
        ap.error("--rounds must be >= 2 (the first is not timed)")
    torch.set_num_threads(args.torch_threads)
    global WORLD_THREADS
    WORLD_THREADS = args.world_threads
    names = args.only or list(VARIANTS)
    runs = {name: SB3Run(VARIANTS[name], args.envs, args.n_steps, args.seed) for name in names}
    try:
        # Rounds alternate between the variants, so that a change in the machine's other load
        # touches all of them alike; the best round of each is kept (load only ever slows one down).
        for _ in range(args.rounds):
            for run in runs.values():
                run.round()
    finally:
        for run in runs.values():
            run.venv.close()
    results = {name: run.result() for name, run in runs.items()}
    for name, r in results.items():
        print(
            f"{name:12s} {r['env_steps_per_s']:9.0f} env-steps/s collecting "
            f"(median {r['env_steps_per_s_median']:.0f}),"
            f" {r['learn_env_steps_per_s']:8.0f} env-steps/s in learn() (best of {r['rounds_timed']} rounds)",
            file=sys.stderr,
        )
    out: dict = {
        "benchmark": "bench_ppo",
        "cpu": cpu_model(),
        "cores": os.cpu_count(),
        "torch": torch.__version__,
        "torch_threads": args.torch_threads,
        "envs": args.envs,
        "n_steps": args.n_steps,
        "rounds_timed": args.rounds - 1,
        "world_threads": args.world_threads,
    }
    try:
        import stable_baselines3

        out["stable_baselines3"] = stable_baselines3.__version__
    except ImportError:
        pass
    for name, r in results.items():
        out[f"{name}_env_steps_per_s"] = round(r["env_steps_per_s"], 1)
        out[f"{name}_env_steps_per_s_median"] = round(r["env_steps_per_s_median"], 1)
        out[f"{name}_learn_env_steps_per_s"] = round(r["learn_env_steps_per_s"], 1)
    if "sb3_adapter" in results:
        for other in ("subproc", "dummy"):
            if f"sb3_{other}" in results:
                a, b = results["sb3_adapter"], results[f"sb3_{other}"]
                out[f"sb3_adapter_speedup_vs_{other}"] = round(a["env_steps_per_s"] / b["env_steps_per_s"], 2)
                out[f"sb3_adapter_speedup_vs_{other}_median"] = round(
                    a["env_steps_per_s_median"] / b["env_steps_per_s_median"], 2
                )
                out[f"sb3_adapter_learn_speedup_vs_{other}"] = round(
                    a["learn_env_steps_per_s"] / b["learn_env_steps_per_s"], 2
                )
    emit(run_record() | out, args)
    return 0


if __name__ == "__main__":
    multiprocessing.freeze_support()
    sys.exit(main())
