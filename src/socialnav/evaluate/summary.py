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

import functools
import math
import zlib
from collections.abc import Sequence
from typing import Any

import numpy as np

from socialnav.metrics import side_case_of_row, summarize_side_preference
from socialnav.metrics.aggregate import column_stats

ID_COLUMNS = ("policy", "scenario", "visibility", "index", "seed", "outcome", "information", "side")
RATE_KEYS = {"success": "success_rate", "collision": "collision_rate", "timeout": "timeout_rate",
             "wall_collision": "wall_collision_rate"}  # NaN on open floors (metrics/obstacles.py)
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
    # every scenario row says which table it belongs to: Table II (multi-human) or Table III's sweeps
    out = [{**summarize_group(key, members), "single_human": key[1] not in multi_human}
           for key, members in groups.items()]
    for key, members in pooled.items():
        scenarios = {m["scenario"] for m in members}
        if len(scenarios) > 1:
            out.append(summarize_group(key, members, pooled_over=sorted(scenarios)))
    return out


def summarize_group(
    key: tuple[str, str, str], rows: Sequence[dict[str, Any]], pooled_over: list[str] | None = None
) -> dict[str, Any]:
    """One summary row of a (policy, scenario, visibility) group of per-episode rows.

    Args:
        key: The group's (policy, scenario, visibility).
        rows: Its per-episode metric rows.
        pooled_over: The scenarios a pooled row is over (None: a single scenario).

    Returns:
        Outcome rates with their CIs, and mean, std, CI and n of every other metric key.
    """
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
    # every row's keys: episodes without a static map lack the map_only metrics' (NaN for them here)
    metric_keys = [k for k in dict.fromkeys(k for r in rows for k in r) if k not in ID_COLUMNS]
    if n == 1:  # one episode (e.g. a scene of a log): the statistics need no arrays
        columns = [_single_value_stats(_as_float(rows[0].get(k))) for k in metric_keys]
    else:
        # column by column: NumPy turns None into NaN under dtype=float
        values = np.empty((n, len(metric_keys)))
        for j, k in enumerate(metric_keys):
            values[:, j] = np.array([r.get(k) for r in rows], dtype=float)
        stats = column_stats(
            values, np.random.default_rng(zlib.crc32("|".join(key).encode())), N_BOOT, CONFIDENCE
        )
        columns = list(zip(*(stats[name].tolist() for name in _STAT_NAMES), strict=True))
    names, picks = _layout(tuple(metric_keys))
    out.update(zip(names, [int(columns[j][i]) if i == 4 else columns[j][i] for j, i in picks], strict=True))
    if any("side" in r for r in rows):
        side = summarize_side_preference([r.get("side", "unlabelled") for r in rows], scenario)
        out.update({f"m6_{k}": v for k, v in side.items()})
    elif passing_side(scenario):  # a one-human encounter among the multi-human cells (Francis (a), (j))
        cases = [encounter_side_case(r) for r in rows]
        out.update({f"m6_{k}": v for k, v in summarize_side_preference(cases, scenario).items()})
        out["single_human"] = False  # a Table II scenario with a side reading, not a sweep
    return out


def encounter_side_case(row: dict[str, Any]) -> str:
    """The M_VI case of a one-human encounter's episode row: ``failed`` unless it succeeded."""
    return "failed" if row.get("outcome") != "success" else side_case_of_row(row)


@functools.lru_cache(maxsize=256)
def passing_side(scenario: str) -> bool:
    """Whether ``scenario`` is a one-human encounter whose passing side is defined (M_VI applies).

    Cached: the report asks it for every episode row.
    """
    from socialnav.scenarios import get_scenario

    try:
        return bool(getattr(get_scenario(scenario), "passing_side", False))
    except KeyError:  # a scenario of a plugin that is not installed here, or "pooled"
        return False


_STAT_NAMES = ("mean", "std", "ci_low", "ci_high", "n")  # the order of column_stats' outputs


@functools.lru_cache(maxsize=256)
def _layout(metric_keys: tuple[str, ...]) -> tuple[tuple[str, ...], tuple[tuple[int, int], ...]]:
    """Summary column names, each with the (metric column, statistic) it takes.

    Outcome rates appear as ``success_rate`` with its CI, navigation time also as
    ``nav_time_s``/``nav_time_s_std``, every other key as ``<key>.mean/.std/.ci_low/.ci_high/.n``. Built once
    per set of keys.
    """
    names: list[str] = []
    picks: list[tuple[int, int]] = []
    for j, k in enumerate(metric_keys):
        if k in RATE_KEYS:
            name = RATE_KEYS[k]
            names += [name, f"{name}_ci_low", f"{name}_ci_high"]
            picks += [(j, 0), (j, 2), (j, 3)]
            continue
        if k == NAV_TIME_KEY:
            names += ["nav_time_s", "nav_time_s_std"]
            picks += [(j, 0), (j, 1)]
        names += [f"{k}.{stat}" for stat in _STAT_NAMES]
        picks += [(j, i) for i in range(len(_STAT_NAMES))]
    return tuple(names), tuple(picks)


def _single_value_stats(value: float) -> tuple[float, float, float, float, int]:
    """What :func:`column_stats` gives for one value: itself, no spread, a point interval."""
    if math.isfinite(value):
        return value, math.nan, value, value, 1
    return math.nan, math.nan, math.nan, math.nan, 0


def _as_float(value: Any) -> float:
    return float("nan") if value is None else float(value)
