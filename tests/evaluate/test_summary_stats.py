"""Group statistics of the evaluation summary against direct computation."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from socialnav.evaluate.summary import summarize_episodes, summarize_group
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


@given(st.lists(st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=64), st.none()),
                min_size=1, max_size=6))
def test_one_episode_group_equals_column_stats(values):
    """The one-row shortcut of summarize_group gives column_stats' numbers (scenes of one episode)."""
    keys = [f"m{j}" for j in range(len(values))] + ["success", "navigation_time"]
    row = {"policy": "p", "scenario": "s", "visibility": "-", "index": 0,
           **dict(zip(keys, values + [1.0, values[0]], strict=False))}
    out = summarize_group(("p", "s", "-"), [row])
    column = np.array([[np.nan if row[k] is None else row[k] for k in keys]])
    stats = column_stats(column, np.random.default_rng(0))
    for j, k in enumerate(keys):
        if k == "success":
            assert out["success_rate"] == out["success_rate_ci_low"] == out["success_rate_ci_high"] == 1.0
            continue
        for name in ("mean", "std", "ci_low", "ci_high", "n"):
            expected, got = stats[name][j], out[f"{k}.{name}"]
            assert (np.isnan(expected) and np.isnan(got)) or expected == got, (k, name, expected, got)
        assert isinstance(out[f"{k}.n"], int)
