"""Kendall's tau-b (hand-computed cases) and the ranking helpers."""

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from socialnav.evaluate.ranking import competition_ranks, kendall_tau_b, ranking_text


def test_identical_and_reversed_orders():
    assert kendall_tau_b([1, 2, 3, 4], [10, 20, 30, 40]) == 1.0
    assert kendall_tau_b([1, 2, 3, 4], [4, 3, 2, 1]) == -1.0


def test_one_swap_without_ties():
    # pairs: 6; one discordant (the swapped 3, 4) -> (5 - 1) / 6
    assert kendall_tau_b([1, 2, 3, 4], [1, 2, 4, 3]) == pytest.approx(4 / 6)


def test_ties_in_one_sample():
    # x = [1, 1, 2, 3], y = [1, 2, 3, 4]: pair (0, 1) tied in x; C = 5, D = 0;
    # n0 = 6, n1 = 1, n2 = 0 -> 5 / sqrt(5 * 6)
    assert kendall_tau_b([1, 1, 2, 3], [1, 2, 3, 4]) == pytest.approx(5 / math.sqrt(30))


def test_ties_in_both_samples():
    # x = [1, 1, 2, 2], y = [1, 2, 1, 2]: concordant (0,3), (1,3)?  pairs:
    # (0,1) tie x; (2,3) tie x; (0,2) tie y; (1,3) tie y; (0,3): x up, y up -> C; (1,2): x up, y down -> D
    # C - D = 0 -> 0
    assert kendall_tau_b([1, 1, 2, 2], [1, 2, 1, 2]) == 0.0
    # x = [1, 2, 2, 3], y = [1, 3, 3, 2]: (0,1) C, (0,2) C, (0,3) C, (1,2) tie both, (1,3) D, (2,3) D
    # C = 3, D = 2, n0 = 6, n1 = 1, n2 = 1 -> 1 / 5
    assert kendall_tau_b([1, 2, 2, 3], [1, 3, 3, 2]) == pytest.approx(1 / 5)


def test_degenerate_cases_are_nan_and_bad_input_raises():
    assert math.isnan(kendall_tau_b([1], [2]))
    assert math.isnan(kendall_tau_b([1, 1, 1], [1, 2, 3]))  # constant sample
    with pytest.raises(ValueError, match="same length"):
        kendall_tau_b([1, 2], [1])
    with pytest.raises(ValueError, match="NaN"):
        kendall_tau_b([1, float("nan")], [1, 2])


@given(st.lists(st.tuples(st.integers(0, 4), st.integers(0, 4)), min_size=2, max_size=8))
def test_tau_b_is_symmetric_bounded_and_flips_sign(pairs):
    x = [float(a) for a, _ in pairs]
    y = [float(b) for _, b in pairs]
    tau = kendall_tau_b(x, y)
    if math.isnan(tau):
        assert len(set(x)) == 1 or len(set(y)) == 1
        return
    assert -1 - 1e-12 <= tau <= 1 + 1e-12
    assert kendall_tau_b(y, x) == pytest.approx(tau)
    assert kendall_tau_b(x, [-v for v in y]) == pytest.approx(-tau)


def test_ranks_and_text():
    assert competition_ranks([0.9, 0.95, 0.9], higher_is_better=True) == [2, 1, 2]
    assert competition_ranks([3.0, 1.0, 2.0], higher_is_better=False) == [3, 1, 2]
    assert ranking_text(["a", "b", "c"], [0.9, 0.95, 0.9], True) == "b > a = c"
    assert ranking_text(["a", "b", "c"], [3.0, 1.0, 2.0], False) == "b > c > a"
