"""Benchmark: batched SARL action selection on CPU, against the machine's dense float32 matmul rate.

Reports env-steps/s (one env-step = choosing the action of one episode: 81 candidate next states scored
by SARL, 5 humans each), ms per action for a single episode, the SARL FLOPs per env-step counted from the
layer sizes (the multiply-adds actually performed; see ``sarl_flops_per_env_step``), the achieved FLOP
rate and its fraction of the float32 matmul rate (1024×1024 @ 1024×1024) measured in the same run.
Inputs are NumPy float64 observations, as the simulator gives them, so the time includes conversion,
the action set, propagation, reward and the agent-centric transform, not only the network.

How the fraction is measured: every timed ``act`` call is followed by a window of back-to-back 1024³
matmuls that lasts as long as the call, and the fraction is (best act rate) / (best matmul rate over
those windows). A virtual machine's speed moves by ±25 % between quarter-second windows; the best
13 ms matmul (``fraction_of_matmul_burst_peak``, this benchmark's earlier definition, still reported)
catches a burst that no 0.2–3 s call can, and so biases the fraction low on a busy host. The same
windows also time ``layer_chain``: the matmuls of SARL's layers alone, at the shapes one block of the
policy uses, with nothing else: what a perfect implementation built on the same matmul routine would
reach (``layer_chain_fraction_of_matmul_peak``), the ceiling of the PyTorch scorer (the native scorer
takes a few states through all layers at a time and is not bound by it).

RGL and model-predictive RGL (Chen et al., IROS 2020) are timed in the same run at B = 256 (the same
scene), next to SARL: RGL's one-step lookahead (constant velocity), and MP-RGL with its learned state
predictor (swept-reward lookahead) at depth/width 1/1 and 2/2. A "decision" is choosing one episode's
action; ms per decision = time of one batched call / B. The issue's goal: a d = 2, w = 2 decision costs
at most 4x a d = 1 decision.
The policy scores with ``--scorer`` (default ``auto``, what ``socialnav evaluate`` uses: the native
SARL evaluator on a CPU with AVX2/FMA, with its AVX-512 kernel where the CPU has AVX-512F; ``--kernel
avx2`` forces the AVX2 kernel, key ``native_kernel`` names the one used). Each batch size is timed a
second time with the PyTorch scorer (``torch``, the training path) in the same run, so both fractions
come from the same conditions.

The last line printed is one JSON object.

    PYTHONPATH=src python benchmarks/bench_policy.py [--threads 2] [--batches 256 1024 4096] [--device cuda]
        [--scorer auto|torch|native] [--kernel auto|avx2|avx512] [--skip-rgl]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable

import numpy as np
import torch

from socialnav.policies.learned import StatePredictor, ValuePolicy, build
from socialnav.policies.learned.native_scoring import KERNEL_ENV, KERNELS, SCORERS

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _machine import add_record_arguments, emit, run_record  # noqa: E402  (benchmarks/ is not a package)

N_ACTIONS = 81


def sarl_flops_per_env_step(n_humans: int, n_actions: int = N_ACTIONS) -> dict[str, float]:
    """FLOPs (2 per multiply-add) of SARL per env-step, from the layer sizes.

    ``performed`` counts what the implementation computes (the global-state half of the first
    attention layer once per state); ``nominal`` the textbook concat [e_i, g] @ W (200 → 100) per human.
    Element-wise work (ReLU, softmax, geometry) is not counted.
    """
    per_human = 2 * (13 * 150 + 150 * 100)  # mlp1
    per_human += 2 * (100 * 100 + 100 * 50)  # mlp2
    per_human += 2 * (100 * 100 + 100 * 100 + 100 * 1)  # attention: e-half of layer 1, layers 2, 3
    per_human += 2 * 50  # weighted sum
    per_state = 2 * (56 * 150 + 150 * 100 + 100 * 100 + 100 * 1)  # mlp3
    performed = n_actions * (n_humans * per_human + per_state + 2 * 100 * 100)  # + g-half once per state
    nominal = n_actions * (n_humans * (per_human + 2 * 100 * 100) + per_state)
    return {"performed": float(performed), "nominal": float(nominal)}


class MatmulWindows:
    """float32 1024³ matmul rate over windows of a given length (the reference of the fraction)."""

    def __init__(self, n: int = 1024, device: str = "cpu") -> None:
        self.n, self.device = n, torch.device(device)
        self.a, self.b, self.c = (torch.randn(n, n, device=self.device) for _ in range(3))
        torch.mm(self.a, self.b, out=self.c)

    def gflops(self, seconds: float) -> float:
        """Back-to-back matmuls for at least ``seconds`` (at least one): their GFLOP/s."""
        count, start = 0, time.perf_counter()
        while True:
            torch.mm(self.a, self.b, out=self.c)
            count += 1
            _sync(self.device)
            elapsed = time.perf_counter() - start
            if elapsed >= seconds:
                return 2 * self.n**3 * count / elapsed / 1e9


def _sync(device: torch.device) -> None:
    if device.type == "cuda":
        torch.cuda.synchronize(device)


def layer_chain(humans: int, states: int, device: str = "cpu") -> tuple[Callable[[], None], float]:
    """SARL's matmuls at one block's shapes (``states`` joint states × ``humans`` rows), nothing else.

    Returns the function running them once and its FLOPs: the multiply-adds of
    ``sarl_flops_per_env_step(humans)["performed"] / 81 * states`` but the attention-weighted sum
    (0.1 % of them), each layer as one addmm with its bias.
    """
    rows = states * humans
    # (in, out, rows): per human mlp1, mlp2[0] fused with attention[0]'s e-half, attention[2], [4],
    # mlp2[2]; per state attention[0]'s g-half, then mlp3.
    per_human = [(13, 150), (150, 100), (100, 200), (100, 100), (100, 1), (100, 50)]
    per_state = [(100, 100), (56, 150), (150, 100), (100, 100), (100, 1)]
    shapes = [(i, o, rows) for i, o in per_human] + [(i, o, states) for i, o in per_state]
    dev = torch.device(device)
    mats = [
        (torch.randn(r, i, device=dev), torch.randn(o, i, device=dev).t(), torch.randn(o, device=dev),
         torch.empty(r, o, device=dev))
        for i, o, r in shapes
    ]

    def run() -> None:
        for x, w, bias, out in mats:
            torch.addmm(bias, x, w, out=out)
        _sync(dev)

    return run, float(sum(2 * i * o * r for i, o, r in shapes))


def matmul_gflops(n: int = 1024, repeats: int = 20) -> float:
    a = torch.randn(n, n)
    b = torch.randn(n, n)
    c = torch.empty(n, n)
    for _ in range(3):
        torch.mm(a, b, out=c)
    best = float("inf")
    for _ in range(repeats):
        t = time.perf_counter()
        torch.mm(a, b, out=c)
        best = min(best, time.perf_counter() - t)
    return 2 * n**3 / best / 1e9


def scene(b: int, n: int, seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    robot = np.zeros((b, 9))
    robot[:, 0:2] = rng.uniform(-4, 4, (b, 2))
    robot[:, 4] = 0.3
    robot[:, 5:7] = rng.uniform(-4, 4, (b, 2))
    robot[:, 7] = 1.0
    humans = np.zeros((b, n, 5))
    humans[..., 0:2] = rng.uniform(-4, 4, (b, n, 2))
    humans[..., 2:4] = rng.uniform(-1, 1, (b, n, 2))
    humans[..., 4] = 0.3
    return {"robot": robot, "humans": humans, "human_mask": np.ones((b, n), bool), "dt": 0.25}


def time_act(policy: ValuePolicy, obs: dict, min_time: float = 1.0, min_reps: int = 3) -> float:
    """Best-of-reps seconds per ``policy.act`` call (after a warm-up)."""
    policy.act(obs)
    times: list[float] = []
    start = time.perf_counter()
    while len(times) < min_reps or time.perf_counter() - start < min_time:
        t = time.perf_counter()
        policy.act(obs)
        times.append(time.perf_counter() - t)
    return float(np.min(times))


def time_paired(
    policy: ValuePolicy,
    obs: dict,
    matmul: MatmulWindows,
    chain: tuple[Callable[[], None], float],
    min_time: float = 1.0,
    min_reps: int = 5,
) -> dict[str, float]:
    """Each ``act`` call followed by a matmul window and a layer-chain window of the same length.

    Returns the best seconds per call, the best matmul GFLOP/s and the best layer-chain GFLOP/s over
    those windows (so a burst of speed or of load counts alike for all three).
    """
    run_chain, chain_flops = chain
    policy.act(obs)
    run_chain()
    best = {"act_s": float("inf"), "matmul_gflops": 0.0, "chain_gflops": 0.0}
    reps, start = 0, time.perf_counter()
    while reps < min_reps or time.perf_counter() - start < min_time:
        t = time.perf_counter()
        policy.act(obs)
        took = time.perf_counter() - t
        best["act_s"] = min(best["act_s"], took)
        best["matmul_gflops"] = max(best["matmul_gflops"], matmul.gflops(took))
        count, t = 0, time.perf_counter()
        while count == 0 or time.perf_counter() - t < took:
            run_chain()
            count += 1
        chain_rate = chain_flops * count / (time.perf_counter() - t) / 1e9
        best["chain_gflops"] = max(best["chain_gflops"], chain_rate)
        reps += 1
    return best


def time_rgl(n_humans: int, min_time: float, device: str, b: int = 256) -> dict[str, float]:
    """RGL and MP-RGL decision costs at batch ``b``, with SARL's in the same conditions."""
    obs = scene(b, n_humans, seed=1)
    torch.manual_seed(1)
    sarl = ValuePolicy(build("sarl"), device=device)
    rgl = ValuePolicy(build("rgl"), device=device)
    net, predictor = build("mp_rgl"), StatePredictor()
    mp = {
        (d, w): ValuePolicy(
            net,
            information="learned",
            predictor=predictor,
            planning_depth=d,
            planning_width=w,
            reward_rule="swept",
            device=device,
        )
        for d, w in ((1, 1), (2, 2))
    }
    # Interleaved best-of-reps: on a shared machine, load that comes and goes then hits every policy
    # alike instead of whichever happened to be timed at that moment.
    policies = {"sarl": sarl, "rgl": rgl, "d1": mp[1, 1], "d2w2": mp[2, 2]}
    best = dict.fromkeys(policies, float("inf"))
    for p in policies.values():
        p.act(obs)  # warm-up
    start = time.perf_counter()
    rounds = 0
    while rounds < 3 or time.perf_counter() - start < 4 * min_time:
        for name, p in policies.items():
            t = time.perf_counter()
            p.act(obs)
            best[name] = min(best[name], time.perf_counter() - t)
        rounds += 1
    t_sarl, t_rgl = best["sarl"], best["rgl"]
    t_mp = {(1, 1): best["d1"], (2, 2): best["d2w2"]}
    print(
        f"B={b}: SARL {b / t_sarl:.0f}, RGL {b / t_rgl:.0f} env-steps/s; MP-RGL d1 "
        f"{t_mp[1, 1] / b * 1e3:.3f} ms, d2w2 {t_mp[2, 2] / b * 1e3:.3f} ms per decision "
        f"(x{t_mp[2, 2] / t_mp[1, 1]:.2f})"
    )
    return {
        "sarl_env_steps_per_s_rgl_run": round(b / t_sarl, 1),
        "rgl_env_steps_per_s": round(b / t_rgl, 1),
        "mp_rgl_d1_env_steps_per_s": round(b / t_mp[1, 1], 1),
        "mp_rgl_d1_ms_per_decision": round(t_mp[1, 1] / b * 1e3, 4),
        "mp_rgl_d2w2_ms_per_decision": round(t_mp[2, 2] / b * 1e3, 4),
        "mp_rgl_d2w2_over_d1": round(t_mp[2, 2] / t_mp[1, 1], 3),
        "rgl_batch": b,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, default=2, help="torch intra-op threads (0: torch default)")
    ap.add_argument("--humans", type=int, default=5)
    ap.add_argument("--batches", type=int, nargs="+", default=[256, 1024, 4096])
    ap.add_argument("--min-time", type=float, default=1.0, help="seconds spent timing each batch size")
    ap.add_argument("--device", default="cpu", help="cpu or cuda (nothing requires a GPU)")
    ap.add_argument("--scorer", default="auto", choices=SCORERS, help="network evaluator")
    ap.add_argument(
        "--kernel", choices=KERNELS, help=f"native scorer's vector kernel (default: ${KERNEL_ENV} or auto)"
    )
    ap.add_argument("--skip-rgl", action="store_true",
                    help="leave out the RGL / MP-RGL timings (a shorter run for the scorer figures alone)")
    add_record_arguments(ap, "bench_policy")
    args = ap.parse_args()
    if args.threads > 0:
        torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    if args.kernel:
        os.environ[KERNEL_ENV] = args.kernel  # read where the native scorer is built
    policy = ValuePolicy(build("sarl"), device=args.device, scorer=args.scorer)
    policy.network.eval()
    torch_policy = ValuePolicy(policy.network, device=args.device, scorer="torch")
    scorer = policy.active_scorer

    peak = matmul_gflops()
    flops = sarl_flops_per_env_step(args.humans)
    print(
        f"torch {torch.__version__}, threads {torch.get_num_threads()}, "
        f"humans {args.humans}, actions {N_ACTIONS}, scorer {scorer}"
        + (f" ({policy.native_kernel} kernel)" if policy.native_kernel else "")
    )
    print(f"float32 matmul 1024^3: {peak:.1f} GFLOP/s")
    print(
        f"SARL FLOPs per env-step: {flops['performed'] / 1e6:.2f} M performed "
        f"({flops['nominal'] / 1e6:.2f} M with the textbook concat attention)"
    )

    one_episode = scene(1, args.humans)
    single = time_act(policy, one_episode, args.min_time)
    single_torch = single if scorer == "torch" else time_act(torch_policy, one_episode, args.min_time)
    print(f"B=1: {single * 1e3:.2f} ms per action (one episode); torch scorer {single_torch * 1e3:.2f} ms")
    matmul = MatmulWindows(device=args.device)
    block_states = policy.states_per_pass or 1024  # the states of one network call on CPU
    chain = layer_chain(args.humans, block_states, args.device)
    results = {}
    for b in args.batches:
        obs = scene(b, args.humans)
        paired = time_paired(policy, obs, matmul, chain, args.min_time)
        t = paired["act_s"]
        steps = b / t
        gflops = steps * flops["performed"] / 1e9
        ref = time_paired(torch_policy, obs, matmul, chain, args.min_time) if scorer != "torch" else paired
        ref_steps = b / ref["act_s"]
        results[b] = {
            "env_steps_per_s": steps,
            "gflops": gflops,
            "fraction": gflops / paired["matmul_gflops"],
            "window_matmul_gflops": paired["matmul_gflops"],
            "chain_fraction": max(paired["chain_gflops"], ref["chain_gflops"])
            / max(paired["matmul_gflops"], ref["matmul_gflops"]),
            "torch_env_steps_per_s": ref_steps,
            "torch_fraction": ref_steps * flops["performed"] / 1e9 / ref["matmul_gflops"],
        }
        print(
            f"B={b}: {t * 1e3:.1f} ms per call, {steps:.0f} env-steps/s, {gflops:.1f} GFLOP/s "
            f"= {results[b]['fraction']:.1%} of matmul over the same windows "
            f"({paired['matmul_gflops']:.1f} GFLOP/s); torch scorer {ref_steps:.0f} env-steps/s = "
            f"{results[b]['torch_fraction']:.1%}; SARL's layer matmuls alone (torch): "
            f"{results[b]['chain_fraction']:.1%}"
        )
    # The burst peak (best 13 ms matmul, before and after): this benchmark's earlier reference.
    burst = max(peak, matmul_gflops())
    print(f"float32 matmul 1024^3 best burst: {burst:.1f} GFLOP/s")
    rgl = {"rgl_skipped": True} if args.skip_rgl else time_rgl(args.humans, args.min_time, args.device)
    head = 256 if 256 in results else args.batches[0]
    best = max(results, key=lambda k: results[k]["fraction"])
    out = {
        "env_steps_per_s": round(results[head]["env_steps_per_s"], 1),
        "batch": head,
        "ms_per_action_single_episode": round(single * 1e3, 3),
        "fraction_of_matmul_peak": round(results[best]["fraction"], 4),
        "fraction_batch": best,
        "fraction_at_batch": {str(k): round(v["fraction"], 4) for k, v in results.items()},
        "fraction_of_matmul_burst_peak": {str(k): round(v["gflops"] / burst, 4) for k, v in results.items()},
        "layer_chain_fraction_of_matmul_peak": {
            str(k): round(v["chain_fraction"], 4) for k, v in results.items()
        },
        "env_steps_per_s_at_batch": {str(k): round(v["env_steps_per_s"], 1) for k, v in results.items()},
        "matmul_gflops": round(results[best]["window_matmul_gflops"], 2),
        "matmul_burst_gflops": round(burst, 2),
        "layer_chain_states": block_states,
        "scorer": scorer,
        "native_kernel": policy.native_kernel,
        "torch_scorer_fraction_at_batch": {str(k): round(v["torch_fraction"], 4) for k, v in results.items()},
        "torch_scorer_env_steps_per_s_at_batch": {
            str(k): round(v["torch_env_steps_per_s"], 1) for k, v in results.items()
        },
        "torch_scorer_ms_per_action_single_episode": round(single_torch * 1e3, 3),
        "sarl_mflops_per_env_step": round(flops["performed"] / 1e6, 3),
        "threads": torch.get_num_threads(),
        "humans": args.humans,
        "device": args.device,
        **rgl,
    }
    emit(run_record() | out, args)


if __name__ == "__main__":
    main()
