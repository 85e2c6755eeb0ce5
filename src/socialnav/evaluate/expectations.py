"""Behaviour fingerprints of the shipped checkpoints (the regression test of their behaviour).

A fingerprint is what a checkpoint does on a fixed small set of test episodes of its own preset
(``EPISODES`` per scenario, invisible robot): per episode the outcome, the number of steps and a
few metrics. ``tests/evaluate/checkpoint_expectations.json`` stores them; the test recomputes them and
compares outcomes and steps exactly and metrics to ``TOLERANCE``, which holds on any x86-64 CPU: the
networks' float32 sums are rounded by whichever kernels PyTorch picks on the CPU (MKL and ATen dispatch
by vendor and ISA), and those last bits reach the continuous metrics, never an outcome or a step count
on the fingerprinted episodes. After a deliberate change (a new or
retrained checkpoint), regenerate the file with ``python tools/update_checkpoint_expectations.py``.
"""

from __future__ import annotations

import math
from typing import Any

EPISODES = 4  # per scenario of the preset (multi-human and single-human)
METRICS = (
    "navigation_time",
    "path_length",
    "min_clearance",
    "m1_personal_space.duration_s@eps=0.2,distance=clearance",
    "m2_projected_path.duration_s@tau=1,anchor=rear",
    "m4_jerk.mean_sq",
)
#: An Intel Xeon moved ``m4_jerk.mean_sq`` by 2.6e-6 of its value against the AMD EPYC that recorded the
#: expectations (37.297584 against 37.297486); other kernels forced on the EPYC (MKL_CBWR=COMPATIBLE,
#: ATEN_CPU_CAPABILITY, ONEDNN_MAX_CPU_ISA) by at most 4.2e-6 (jerk), 6e-7 (clearance), 2.4e-7 (path
#: length). 1e-4 leaves 20 times that; a changed policy or simulator changes outcomes, steps or metrics
#: by far more.
TOLERANCE = {"rel": 1e-4, "abs": 1e-6}


def fingerprint(entry: Any) -> list[dict[str, Any]]:
    """Per-episode outcome, steps and ``METRICS`` of a shipped checkpoint (``ShippedCheckpoint``)."""
    import warnings

    import torch

    from socialnav.evaluate.execution import simulate_chunk
    from socialnav.evaluate.plan import plan_cells
    from socialnav.metrics import score_episode
    from socialnav.policies.building import build_policy
    from socialnav.presets import load_preset

    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # results do not depend on it; one thread is fastest for tiny batches
    try:
        preset = load_preset(entry.preset)
        policy = build_policy(entry.policy, preset, entry.path)
        rows = []
        for cell in plan_cells(preset, episodes=EPISODES, visibility="invisible"):
            for traj in simulate_chunk(policy, preset, cell, 0, cell.episodes, entry.name):
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")  # M_V's v_pref warning: M_V is not fingerprinted
                    scores = score_episode(traj)
                rows.append({
                    "scenario": cell.scenario,
                    "index": traj.settings["index"],
                    "outcome": traj.outcome,
                    "steps": int(traj.positions.shape[0] - 1),
                    **{k: _num(scores[k]) for k in METRICS},
                })
        return rows
    finally:
        torch.set_num_threads(threads)


def compare(expected: list[dict[str, Any]], actual: list[dict[str, Any]]) -> list[str]:
    """Differences, one line each (empty when the behaviour is unchanged)."""
    problems = []
    exp = {(r["scenario"], r["index"]): r for r in expected}
    act = {(r["scenario"], r["index"]): r for r in actual}
    if exp.keys() != act.keys():
        return [f"episodes differ: expected {sorted(exp)}, got {sorted(act)}"]
    for key in sorted(exp):
        e, a = exp[key], act[key]
        for field in ("outcome", "steps"):
            if e[field] != a[field]:
                problems.append(f"{key}: {field} {a[field]!r}, expected {e[field]!r}")
        for k in METRICS:
            ev, av = e.get(k), a.get(k)
            if ev is None or av is None:
                if ev != av:
                    problems.append(f"{key}: {k} {av}, expected {ev}")
            elif not math.isclose(av, ev, rel_tol=TOLERANCE["rel"], abs_tol=TOLERANCE["abs"]):
                problems.append(f"{key}: {k} {av!r}, expected {ev!r}")
    return problems


def _num(x: float) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)
