"""PPO throughput on socialnav: Stable-Baselines3 on the native vector env (SocialNavVecEnv) vs the same
PPO on SB3's SubprocVecEnv and DummyVecEnv of the single Gymnasium env, in one run.

Every variant trains the same PPO (``MultiInputPolicy``, SB3's default network and hyperparameters
except ``n_steps``) on circle crossing with 5 ORCA humans, ``--envs`` environments, the same
observation (socialnav.sim.learner_obs defaults: float32, world frame). Measured per variant:

- ``env_steps_per_s``: env-steps collected per second of SB3's rollout collection (policy inference,
  stepping, buffer writes: everything the VecEnv choice changes), the first rollout (resets, process
  start-up) left out;
- ``learn_env_steps_per_s``: env-steps per second of the whole ``learn()`` (collection plus the PPO
  update, which does not depend on the VecEnv), the first rollout left out likewise.

``sb3_adapter_speedup_vs_subproc`` / ``_vs_dummy`` are ratios of ``env_steps_per_s`` (goal >= 5 vs
SubprocVecEnv, issue #29). SubprocVecEnv uses the ``fork`` start method (the children share the
parent's imported modules; ``forkserver`` would import torch in each of the 64 processes).

    python benchmarks/bench_ppo.py [--envs 64] [--n-steps 64] [--rollouts 3] [--only sb3_adapter ...]

Prints one line per variant, then one JSON object last. Later trainers (the project's own PPO) add
their variants to VARIANTS under their own keys.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import platform
import sys
import time

import torch

SCENARIO = {"scenario": "circle_crossing", "scenario_params": {"n_humans": 5}}


def _rollout_timer():
    from stable_baselines3.common.callbacks import BaseCallback

    class RolloutTimer(BaseCallback):
        """Collection seconds per rollout (SB3 calls on_rollout_start/end around collect_rollouts)."""

        def __init__(self):
            super().__init__()
            self.collect: list[float] = []
            self.marks: list[float] = []

        def _on_rollout_start(self) -> None:
            self._t0 = time.perf_counter()
            self.marks.append(self._t0)

        def _on_rollout_end(self) -> None:
            self.collect.append(time.perf_counter() - self._t0)

        def _on_step(self) -> bool:
            return True

    return RolloutTimer()


def _single_env_factory():
    import gymnasium as gym

    import socialnav  # noqa: F401  (registers the ids)
    from socialnav.sim.learner_wrappers import LearnerObservation

    env = gym.make("socialnav/CircleCrossing-v0", scenario_params=SCENARIO["scenario_params"])
    return LearnerObservation(env)


def make_sb3_adapter(n: int):
    from socialnav.integrations.sb3 import SocialNavVecEnv

    return SocialNavVecEnv(SCENARIO["scenario"], n, scenario_params=SCENARIO["scenario_params"])


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


def measure_sb3(make_env, envs: int, n_steps: int, rollouts: int, seed: int) -> dict:
    from stable_baselines3 import PPO

    venv = make_env(envs)
    try:
        model = PPO("MultiInputPolicy", venv, n_steps=n_steps, seed=seed, device="cpu", verbose=0)
        timer = _rollout_timer()
        model.learn(envs * n_steps * rollouts, callback=timer)
        end = time.perf_counter()
    finally:
        venv.close()
    steps = envs * n_steps * (rollouts - 1)  # the first rollout (resets, start-up) is left out
    collect = sum(timer.collect[1:])
    learn = end - timer.marks[1]
    return {
        "env_steps_per_s": steps / collect,
        "learn_env_steps_per_s": steps / learn,
        "collect_seconds": collect,
        "learn_seconds": learn,
        "env_steps_timed": steps,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--envs", type=int, default=64)
    ap.add_argument("--n-steps", type=int, default=64, help="PPO n_steps (per env and rollout)")
    ap.add_argument("--rollouts", type=int, default=3, help="rollouts per variant (the first is not timed)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--only", nargs="+", choices=sorted(VARIANTS), help="measure only these variants")
    args = ap.parse_args(argv)
    if args.rollouts < 2:
        ap.error("--rollouts must be >= 2 (the first is not timed)")
    torch.set_num_threads(os.cpu_count() or 1)
    results = {}
    for name in args.only or VARIANTS:
        r = measure_sb3(VARIANTS[name], args.envs, args.n_steps, args.rollouts, args.seed)
        results[name] = r
        print(
            f"{name:12s} {r['env_steps_per_s']:9.0f} env-steps/s collecting, "
            f"{r['learn_env_steps_per_s']:8.0f} env-steps/s in learn() ({r['env_steps_timed']} env-steps)",
            file=sys.stderr,
        )
    out: dict = {
        "benchmark": "bench_ppo",
        "cpu": platform.processor() or platform.machine(),
        "cores": os.cpu_count(),
        "torch": torch.__version__,
        "envs": args.envs,
        "n_steps": args.n_steps,
        "rollouts_timed": args.rollouts - 1,
    }
    try:
        import stable_baselines3

        out["stable_baselines3"] = stable_baselines3.__version__
    except ImportError:
        pass
    for name, r in results.items():
        out[f"{name}_env_steps_per_s"] = round(r["env_steps_per_s"], 1)
        out[f"{name}_learn_env_steps_per_s"] = round(r["learn_env_steps_per_s"], 1)
    if "sb3_adapter" in results:
        for other in ("subproc", "dummy"):
            if f"sb3_{other}" in results:
                a, b = results["sb3_adapter"], results[f"sb3_{other}"]
                out[f"sb3_adapter_speedup_vs_{other}"] = round(a["env_steps_per_s"] / b["env_steps_per_s"], 2)
                out[f"sb3_adapter_learn_speedup_vs_{other}"] = round(
                    a["learn_env_steps_per_s"] / b["learn_env_steps_per_s"], 2
                )
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    multiprocessing.freeze_support()
    sys.exit(main())
