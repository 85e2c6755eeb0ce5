"""Group statistics of the evaluation summary against direct computation."""

import numpy as np
import pytest

from socialnav.evaluate.summary import summarize_episodes
from socialnav.metrics.aggregate import column_stats


def test_column_stats_match_numpy_and_ignore_nans():
    rng = np.random.default_rng(0)
    values = rng.normal(size=(300, 3))
    values[::4, 1] = np.nan  # a social metric: NaN on failed episodes
    values[:, 2] = np.nan
    stats = column_stats(values, np.random.default_rng(1))
    assert stats["mean"][0] == pytest.approx(values[:, 0].mean())
    assert stats["std"][0] == pytest.approx(values[:, 0].std(ddof=1))
    assert stats["mean"][1] == pytest.approx(np.nanmean(values[:, 1]))
    assert stats["n"].tolist() == [300, 225, 0]
    assert np.isnan(stats["mean"][2]) and np.isnan(stats["ci_low"][2])
    # A 95 % CI of the mean is about ±1.96 σ/√n around it.
    half = 1.96 * values[:, 0].std(ddof=1) / np.sqrt(300)
    assert stats["ci_low"][0] == pytest.approx(stats["mean"][0] - half, abs=0.35 * half)
    assert stats["ci_high"][0] == pytest.approx(stats["mean"][0] + half, abs=0.35 * half)


def test_bootstrap_is_deterministic_and_order_independent():
    rows = [
        {
            "policy": "p",
            "scenario": s,
            "visibility": "invisible",
            "index": i,
            "success": float(i % 3 != 0),
            "collision": float(i % 3 == 0),
            "timeout": 0.0,
            "navigation_time": 8.0 + i % 5,
        }
        for s in ("random", "circle_crossing")
        for i in range(50)
    ]
    a = summarize_episodes(rows, multi_human=("random", "circle_crossing"))
    b = summarize_episodes(list(reversed(rows)), multi_human=("random", "circle_crossing"))
    key = {(r["scenario"]): r for r in a}
    key_b = {(r["scenario"]): r for r in b}
    for s in ("random", "circle_crossing", "pooled"):
        assert key[s]["success_rate"] == pytest.approx(key_b[s]["success_rate"])
        assert key[s]["success_rate_ci_low"] == key_b[s]["success_rate_ci_low"]
    assert key["pooled"]["episodes"] == 100
    assert key["pooled"]["success_rate"] == pytest.approx(2 / 3, abs=0.01)
