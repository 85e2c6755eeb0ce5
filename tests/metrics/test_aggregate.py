"""summarize: mean, std, percentile-bootstrap CI, NaN handling, determinism."""

from __future__ import annotations

import math

import numpy as np
import pytest

from socialnav.metrics.aggregate import summarize, summarize_rows


def test_hand_values_and_nan_ignored() -> None:
    out = summarize([1.0, 2.0, 3.0, float("nan")])
    assert out["mean"] == 2.0 and out["std"] == 1.0 and out["n"] == 3.0
    assert 1.0 <= out["ci_low"] <= 2.0 <= out["ci_high"] <= 3.0


def test_empty_and_single() -> None:
    empty = summarize([float("nan")])
    assert empty["n"] == 0.0 and all(math.isnan(empty[k]) for k in ("mean", "std", "ci_low", "ci_high"))
    assert summarize([]) == pytest.approx(empty, nan_ok=True)
    one = summarize([4.0])
    assert one["mean"] == one["ci_low"] == one["ci_high"] == 4.0 and math.isnan(one["std"])


def test_constant_values_give_degenerate_ci() -> None:
    out = summarize(np.full(50, 0.25))
    assert out["ci_low"] == out["ci_high"] == 0.25 and out["std"] == 0.0


def test_deterministic_default_and_explicit_generator() -> None:
    x = np.random.default_rng(5).exponential(size=40)
    assert summarize(x) == summarize(x)
    a = summarize(x, np.random.default_rng(1))
    assert a == summarize(x, np.random.default_rng(1))
    assert a != summarize(x, np.random.default_rng(2))


def test_ci_matches_normal_theory() -> None:
    x = np.random.default_rng(7).normal(10.0, 2.0, size=400)
    out = summarize(x, n_boot=4000)
    half = 1.96 * x.std(ddof=1) / math.sqrt(x.size)
    assert out["ci_high"] - out["ci_low"] == pytest.approx(2 * half, rel=0.1)
    assert out["ci_low"] < x.mean() < out["ci_high"]


def test_summarize_rows() -> None:
    rows = [{"a": 1.0, "b": float("nan")}, {"a": 3.0, "b": 2.0}, {"a": 2.0}]
    out = summarize_rows(rows)
    assert list(out) == ["a", "b"]
    assert out["a"]["mean"] == 2.0 and out["b"]["n"] == 1.0
    with pytest.raises(ValueError, match="confidence"):
        summarize([1.0], confidence=1.5)


def test_summarize_rows_states_population_per_column() -> None:
    import numpy as np

    from socialnav.metrics import score_episode
    from socialnav.trajectory import Trajectory

    k = np.arange(9)
    pos = np.stack([np.stack([0 * k, -2 + 0.5 * k], 1), np.tile([1.0, 0.0], (9, 1))], 1)
    rows = [
        score_episode(Trajectory.from_positions(pos, 0.25, radii=0.3, goals=pos[-1], outcome=o))
        for o in ("success", "collision", "success")
    ]
    out = summarize_rows(rows)
    assert out["path_length"]["population"] == "all" and out["path_length"]["n"] == 3.0
    assert out["success"]["population"] == "known_outcome" and out["success"]["mean"] == pytest.approx(2 / 3)
    assert out["navigation_time"]["population"] == "success" and out["navigation_time"]["n"] == 2.0
    key = "m1_personal_space.count@eps=0.2,distance=clearance"
    assert out[key]["population"] == "success" and out[key]["n"] == 2.0 and out[key]["n_rows"] == 3.0
    assert summarize_rows(rows, require_success=False)[key]["population"] == "all"
    assert summarize_rows([{"custom": 1.0}])["custom"]["population"] == "unknown"
