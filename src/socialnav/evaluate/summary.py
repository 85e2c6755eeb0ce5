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
from socialnav.metrics.aggregate import column_stats

ID_COLUMNS = ("policy", "scenario", "visibility", "index", "seed", "outcome", "information", "side")
RATE_KEYS = {"success": "success_rate", "collision": "collision_rate", "timeout": "timeout_rate"}
NAV_TIME_KEY = "navigation_time"
N_BOOT = 1000
CONFIDENCE = 0.95


def summarize_episodes(
    rows: Sequence[dict[str, Any]], multi_human: Sequence[str] = ()
) -> list[dict[str, Any]]:
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


def summarize_group(
    key: tuple[str, str, str], rows: Sequence[dict[str, Any]], pooled_over: list[str] | None = None
) -> dict[str, Any]:
    policy, scenario, visibility = key
    # A canonical order makes the bootstrap independent of the order rows were read in.
    rows = sorted(rows, key=lambda r: (str(r.get("scenario", "")), int(r.get("index", 0))))
    n = len(rows)
    out: dict[str, Any] = {
        "policy": policy,
        "scenario": scenario,
        "visibility": visibility,
        "information": rows[0].get("information", ""),
        "episodes": n,
    }
    if pooled_over:
        out["pooled_over"] = ",".join(pooled_over)
    metric_keys = [k for k in rows[0] if k not in ID_COLUMNS]
    values = np.array([[_as_float(r.get(k)) for k in metric_keys] for r in rows]).reshape(n, len(metric_keys))
    stats = column_stats(
        values, np.random.default_rng(zlib.crc32("|".join(key).encode())), N_BOOT, CONFIDENCE
    )
    for j, k in enumerate(metric_keys):
        col = {name: stat[j] for name, stat in stats.items()}
        if k in RATE_KEYS:
            name = RATE_KEYS[k]
            out[name] = col["mean"]
            out[f"{name}_ci_low"], out[f"{name}_ci_high"] = col["ci_low"], col["ci_high"]
            continue
        if k == NAV_TIME_KEY:
            out["nav_time_s"], out["nav_time_s_std"] = col["mean"], col["std"]
        for stat, value in col.items():
            out[f"{k}.{stat}"] = int(value) if stat == "n" else float(value)
    if any("side" in r for r in rows):
        side = summarize_side_preference([r.get("side", "unlabelled") for r in rows], scenario)
        out.update({f"m6_{k}": v for k, v in side.items()})
    return out


def _as_float(value: Any) -> float:
    return float("nan") if value is None else float(value)
