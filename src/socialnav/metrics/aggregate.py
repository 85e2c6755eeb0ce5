"""Aggregation of per-episode metric values: mean, std and a percentile-bootstrap 95 % CI.

Randomness is explicit: pass a ``np.random.Generator``; the default is a fixed seed so that tables
are reproducible run to run.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

import numpy as np

__all__ = ["DEFAULT_SEED", "summarize", "summarize_rows"]

DEFAULT_SEED = 0
"""Seed of the generator used when none is passed."""
_MAX_RESAMPLE_CELLS = 2_000_000  # bound memory of one bootstrap batch (n_boot × n indices)


def summarize(
    values: Iterable[float],
    rng: np.random.Generator | None = None,
    *,
    n_boot: int = 2000,
    confidence: float = 0.95,
) -> dict[str, float]:
    """Mean, standard deviation and bootstrap confidence interval of the mean.

    NaNs are ignored (e.g. social metrics of failed episodes). The CI is the percentile bootstrap:
    the (1 ± confidence)/2 quantiles of ``n_boot`` resampled means.

    Args:
        values: Per-episode values, shape (n,).
        rng: Generator for the resampling; default ``np.random.default_rng(DEFAULT_SEED)``.
        n_boot: Number of bootstrap resamples.
        confidence: Coverage of the interval, in (0, 1).

    Returns:
        ``mean``, ``std`` (sample std, ddof = 1; NaN for n < 2), ``ci_low``, ``ci_high`` and ``n``
        (finite values used). All NaN but ``n`` = 0 when there are no values.
    """
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    x = np.asarray(list(values) if not isinstance(values, np.ndarray) else values, dtype=np.float64)
    x = x[~np.isnan(x.reshape(-1))]
    n = x.size
    if n == 0:
        nan = float("nan")
        return {"mean": nan, "std": nan, "ci_low": nan, "ci_high": nan, "n": 0.0}
    rng = np.random.default_rng(DEFAULT_SEED) if rng is None else rng
    means = np.empty(n_boot)
    batch = max(1, _MAX_RESAMPLE_CELLS // n)
    for start in range(0, n_boot, batch):
        stop = min(n_boot, start + batch)
        means[start:stop] = x[rng.integers(0, n, size=(stop - start, n))].mean(axis=1)
    alpha = (1.0 - confidence) / 2.0
    low, high = np.quantile(means, [alpha, 1.0 - alpha])
    return {
        "mean": float(x.mean()),
        "std": float(x.std(ddof=1)) if n > 1 else float("nan"),
        "ci_low": float(low),
        "ci_high": float(high),
        "n": float(n),
    }


def summarize_rows(
    rows: Sequence[Mapping[str, float]],
    rng: np.random.Generator | None = None,
    **kwargs: float,
) -> dict[str, dict[str, float]]:
    """Summarise each key of per-episode rows (e.g. from ``score_episode``).

    Keys are processed in the order of the first row, then any new ones; one generator is shared,
    so the result depends only on ``rng`` and the rows.

    Returns:
        ``{key: summarize(values of key)}``; a row missing a key counts as NaN for it.
    """
    rng = np.random.default_rng(DEFAULT_SEED) if rng is None else rng
    keys = list(dict.fromkeys(k for row in rows for k in row))
    return {k: summarize([row.get(k, np.nan) for row in rows], rng, **kwargs) for k in keys}
