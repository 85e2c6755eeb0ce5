"""Robustness of the ranking: does a metric order the policies the same way under another human model?

Kendall's τ-b between two samples x, y of n paired values (Kendall 1945; ties in either sample):

    τ_b = (C − D) / sqrt((n0 − n1)(n0 − n2))

with C/D the concordant/discordant pairs (a pair tied in x or in y is neither), n0 = n(n−1)/2,
n1 = Σ t(t−1)/2 over groups of ties in x, n2 likewise in y. τ_b is NaN when n < 2 or when either
sample is constant (the denominator is 0). Computed on the values (τ is unchanged by the metric's
direction as long as both samples share it); ranks are only for display.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence


def kendall_tau_b(x: Sequence[float], y: Sequence[float]) -> float:
    """Kendall's τ-b of paired samples (O(n²): meant for a handful of policies).

    Raises:
        ValueError: x and y differ in length or hold NaN.
    """
    if len(x) != len(y):
        raise ValueError(f"x and y must have the same length, got {len(x)} and {len(y)}")
    if any(math.isnan(v) for v in (*x, *y)):
        raise ValueError("x and y must not hold NaN (drop the pairs first)")
    n = len(x)
    if n < 2:
        return math.nan
    concordant = discordant = 0
    for i in range(n):
        for j in range(i + 1, n):
            s = _sign(x[i] - x[j]) * _sign(y[i] - y[j])
            concordant += s > 0
            discordant += s < 0
    n0 = n * (n - 1) / 2
    n1 = sum(t * (t - 1) / 2 for t in Counter(x).values())
    n2 = sum(t * (t - 1) / 2 for t in Counter(y).values())
    denominator = math.sqrt((n0 - n1) * (n0 - n2))
    return math.nan if denominator == 0 else (concordant - discordant) / denominator


def _sign(v: float) -> int:
    return (v > 0) - (v < 0)


def competition_ranks(values: Sequence[float], higher_is_better: bool) -> list[int]:
    """Rank 1 = best; tied values share the best rank of their group ("1224" ranking)."""
    key = [(-v if higher_is_better else v) for v in values]
    return [1 + sum(k < mine for k in key) for mine in key]


def ranking_text(names: Sequence[str], values: Sequence[float], higher_is_better: bool) -> str:
    """``a > b = c``: best first, ``=`` between tied values."""
    order = sorted(range(len(names)), key=lambda i: (-values[i] if higher_is_better else values[i], names[i]))
    parts = [names[order[0]]] if order else []
    for prev, cur in zip(order, order[1:], strict=False):
        parts.append(("= " if values[cur] == values[prev] else "> ") + names[cur])
    return " ".join(parts)
