"""EpisodeRandom: counter-based draws keyed by (seed, salt, key), independent across rows."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from socialnav.scenarios.episode_random import EpisodeRandom, salt_hash


def _ks_uniform(u: np.ndarray) -> float:
    """Kolmogorov-Smirnov statistic of a sample against U(0, 1)."""
    x = np.sort(u)
    n = x.size
    grid = np.arange(1, n + 1) / n
    return float(max(np.max(grid - x), np.max(x - (grid - 1.0 / n))))


def test_shapes_and_ranges() -> None:
    rng = EpisodeRandom(np.arange(7), "s")
    assert rng.uniform((1,)).shape == (7,)
    assert rng.uniform((1,), size=3).shape == (7, 3)
    assert rng.uniform((1,), size=(2, 3)).shape == (7, 2, 3)
    u = rng.uniform((2,), -3.0, 5.0, size=1000)
    assert u.min() >= -3.0 and u.max() < 5.0
    k = rng.integers((3,), -2, 3, size=1000)
    assert k.dtype == np.int64 and set(np.unique(k)) == {-2, -1, 0, 1, 2}
    s = rng.choice_sign((4,), size=1000)
    assert set(np.unique(s)) == {-1.0, 1.0}


def test_deterministic_and_call_order_free() -> None:
    a = EpisodeRandom(np.array([5, 6, 7]), "circle_crossing")
    b = EpisodeRandom(np.array([5, 6, 7]), "circle_crossing")
    x1 = a.uniform((1, 2, 3), size=4)
    a.uniform((9,), size=100)  # unrelated draws in between change nothing
    np.testing.assert_array_equal(a.uniform((1, 2, 3), size=4), x1)
    np.testing.assert_array_equal(b.uniform((1, 2, 3), size=4), x1)


@settings(max_examples=50, deadline=None)
@given(
    seeds=st.lists(st.integers(-(2**63), 2**63 - 1), min_size=1, max_size=20),
    key=st.lists(st.integers(-(2**40), 2**40), min_size=0, max_size=4),
    data=st.data(),
)
def test_rows_independent_of_batch(seeds: list[int], key: list[int], data: st.DataObject) -> None:
    full = EpisodeRandom(np.array(seeds, dtype=np.int64), "salt")
    ref = full.bits(tuple(key), 3)
    perm = data.draw(st.permutations(range(len(seeds))))
    perm_rng = EpisodeRandom(np.array(seeds, dtype=np.int64)[perm], "salt")
    np.testing.assert_array_equal(perm_rng.bits(tuple(key), 3), ref[perm])
    for b, s in enumerate(seeds):
        np.testing.assert_array_equal(
            EpisodeRandom(np.array([s]), "salt").bits(tuple(key), 3), ref[b : b + 1]
        )
    np.testing.assert_array_equal(full.take(np.array(perm)).bits(tuple(key), 3), ref[perm])


def test_element_prefix_stable() -> None:
    """Asking for more elements does not change the first ones."""
    rng = EpisodeRandom(np.arange(4), "x")
    np.testing.assert_array_equal(rng.uniform((1,), size=10)[:, :3], rng.uniform((1,), size=3))


def test_salts_keys_seeds_differ() -> None:
    seeds = np.arange(1000)
    base = EpisodeRandom(seeds, "circle_crossing").random((3, 0, 0))
    others = [
        EpisodeRandom(seeds, "random").random((3, 0, 0)),
        EpisodeRandom(seeds, "circle_crossing").random((3, 0, 1)),
        EpisodeRandom(seeds, "circle_crossing").random((3, 1, 0)),
        EpisodeRandom(seeds, "circle_crossing").random((3, 0)),
        EpisodeRandom(seeds, "circle_crossing").random((3, 0, 0, 0)),
        EpisodeRandom(seeds + 1, "circle_crossing").random((3, 0, 0)),
    ]
    for o in others:
        assert np.mean(o == base) < 0.01
        assert abs(np.corrcoef(o, base)[0, 1]) < 0.1
    assert np.unique(base).size == base.size


def test_salt_hash_stable_across_processes() -> None:
    """Python's str hash is salted per process; ours must not be."""
    code = "from socialnav.scenarios.episode_random import salt_hash; print(salt_hash('circle_crossing'))"
    out = {
        subprocess.run(
            [sys.executable, "-c", code],
            capture_output=True,
            text=True,
            check=True,
            env={"PYTHONHASHSEED": str(h), **_env()},
        ).stdout.strip()
        for h in (1, 2)
    }
    assert out == {str(salt_hash("circle_crossing"))}
    assert salt_hash("a") != salt_hash("b")


def _env() -> dict[str, str]:
    import os

    return {k: v for k, v in os.environ.items() if k != "PYTHONHASHSEED"}


@pytest.mark.parametrize("layout", ["over_seeds", "over_elements", "over_keys"])
def test_uniformity(layout: str) -> None:
    n = 100_000
    if layout == "over_seeds":
        u = EpisodeRandom(np.arange(n), "s").random((1, 2))
    elif layout == "over_elements":
        u = EpisodeRandom(np.array([42]), "s").random((1, 2), n)[0]
    else:
        rng = EpisodeRandom(np.arange(100), "s")
        u = np.concatenate([rng.random((7, k)) for k in range(n // 100)])
    assert abs(u.mean() - 0.5) < 0.005  # sd of the mean: 0.0009
    assert abs(u.var() - 1.0 / 12.0) < 0.002
    assert _ks_uniform(u) < 1.63 / np.sqrt(u.size)  # KS critical value at 1 %
    # Pairs of consecutive values are uncorrelated and fill the unit square evenly.
    assert abs(np.corrcoef(u[:-1], u[1:])[0, 1]) < 0.02
    counts = np.histogram2d(u[:-1], u[1:], bins=10, range=[[0, 1], [0, 1]])[0]
    expected = (u.size - 1) / 100
    chi2 = float(((counts - expected) ** 2 / expected).sum())
    assert chi2 < 160  # 99 d.o.f.; P(chi2 > 160) < 1e-4


def test_bits_low_bit_balance() -> None:
    h = EpisodeRandom(np.arange(20_000), "s").bits((0,))
    bits = (h[:, None] >> np.arange(64, dtype=np.uint64)) & np.uint64(1)
    frac = bits.mean(axis=0)
    assert np.all(np.abs(frac - 0.5) < 0.02)


def test_bad_inputs() -> None:
    with pytest.raises(ValueError, match="1-D"):
        EpisodeRandom(np.zeros((2, 2), dtype=np.int64), "s")
    with pytest.raises(TypeError, match="integers"):
        EpisodeRandom(np.array([0.5]), "s")
    rng = EpisodeRandom(np.arange(3), "s")
    with pytest.raises(TypeError, match="tuple"):
        rng.random([1, 2])  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="high - low"):
        rng.integers((1,), 3, 3)
