"""Aggregation of per-episode rows: mean, std and 95 % bootstrap CI per group.

Groups are (policy, scenario, visibility), plus ``pooled`` over the multi-human scenarios.
Basic rates use every episode; social metrics are NaN on unsuccessful episodes and so are
averaged over successful ones (the paper's convention); NaNs never enter a mean.

The bootstrap draws one set of resampling weights per group and reuses it for every column:
a resampled mean is ``W @ v / W @ 1`` with W the (n_boot, n) multinomial counts, so all
columns of a group cost two matrix-vector products each (percentile interval, 1000 resamples,
seeded by the group's name so that a result never depends on the order groups are computed in).
"""

from __future__ import annotations

import zlib
from collections.abc import Sequence
from typing import Any

import numpy as np

from socialnav.metrics import summarize_side_preference

ID_COLUMNS = ("policy", "scenario", "visibility", "index", "seed", "outcome", "information", "side")
RATE_KEYS = {"success": "success_rate", "collision": "collision_rate", "timeout": "timeout_rate"}
NAV_TIME_KEY = "navigation_time"
N_BOOT = 1000
CONFIDENCE = 0.95


def summarize_episodes(rows: Sequence[dict[str, Any]], multi_human: Sequence[str] = ()) -> list[dict[str, Any]]:
    """One summary row per (policy, scenario, visibility) and per pooled multi-human group."""
    groups: dict[tuple[str, str, str], list[dict[str, Any]]] = {}
    for row in rows:
        groups.setdefault((row["policy"], row["scenario"], row["visibility"]), []).append(row)
    pooled: dict[tuple[str, str, str], list[dict[str, Any]]] = {}
    for (policy, scenario, visibility), members in groups.items():
        if scenario in multi_human:
            pooled.setdefault((policy, "pooled", visibility), []).extend(members)
    out = [summarize_group(key, members) for key, members in groups.items()]
    for key, members in pooled.items():
        scenarios = {m["scenario"] for m in members}
        if len(scenarios) > 1:
            out.append(summarize_group(key, members, pooled_over=sorted(scenarios)))
    return out


def summarize_group(key: tuple[str, str, str], rows: Sequence[dict[str, Any]],
                    pooled_over: list[str] | None = None) -> dict[str, Any]:
    policy, scenario, visibility = key
    n = len(rows)
    rng = np.random.default_rng(zlib.crc32("|".join(key).encode()))
    weights = rng.multinomial(n, np.full(n, 1.0 / n), size=N_BOOT).astype(float)
    out: dict[str, Any] = {"policy": policy, "scenario": scenario, "visibility": visibility,
                           "information": rows[0].get("information", ""), "episodes": n}
    if pooled_over:
        out["pooled_over"] = ",".join(pooled_over)
    metric_keys = [k for k in rows[0] if k not in ID_COLUMNS]
    for k in metric_keys:
        values = np.array([_as_float(r.get(k)) for r in rows])
        stats = _stats(values, weights)
        if k in RATE_KEYS:
            name = RATE_KEYS[k]
            out[name] = stats["mean"]
            out[f"{name}_ci_low"], out[f"{name}_ci_high"] = stats["ci_low"], stats["ci_high"]
            continue
        if k == NAV_TIME_KEY:
            out["nav_time_s"], out["nav_time_s_std"] = stats["mean"], stats["std"]
        for stat, value in stats.items():
            out[f"{k}.{stat}"] = value
    if any("side" in r for r in rows):
        side = summarize_side_preference([r.get("side", "unlabelled") for r in rows], scenario)
        out.update({f"m6_{k}": v for k, v in side.items()})
    return out


def _as_float(value: Any) -> float:
    return float("nan") if value is None else float(value)


def _stats(values: np.ndarray, weights: np.ndarray) -> dict[str, float]:
    valid = np.isfinite(values)
    k = int(valid.sum())
    if k == 0:
        return {"mean": np.nan, "std": np.nan, "ci_low": np.nan, "ci_high": np.nan, "n": 0}
    v = values[valid]
    filled = np.where(valid, values, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        means = (weights @ filled) / (weights @ valid.astype(float))
    lo, hi = np.nanpercentile(means, [50 * (1 - CONFIDENCE), 50 * (1 + CONFIDENCE)]) if k > 1 else (v[0], v[0])
    return {"mean": float(v.mean()), "std": float(v.std(ddof=1)) if k > 1 else np.nan,
            "ci_low": float(lo), "ci_high": float(hi), "n": k}
