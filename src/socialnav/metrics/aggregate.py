"""Aggregation of per-episode metric values: mean, std and a percentile-bootstrap 95 % CI.

Randomness is explicit: pass a ``np.random.Generator``; the default is a fixed seed so that tables
are reproducible run to run.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

import numpy as np

__all__ = ["DEFAULT_SEED", "column_stats", "metric_population", "summarize", "summarize_rows"]

DEFAULT_SEED = 0
"""Seed of the generator used when none is passed."""


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
    x = np.asarray(list(values) if not isinstance(values, np.ndarray) else values, dtype=np.float64).reshape(
        -1
    )
    x = x[~np.isnan(x)]
    rng = np.random.default_rng(DEFAULT_SEED) if rng is None else rng
    stats = column_stats(x[:, None], rng, n_boot, confidence)
    return {name: float(value[0]) for name, value in stats.items()}


def summarize_rows(
    rows: Sequence[Mapping[str, float]],
    rng: np.random.Generator | None = None,
    *,
    require_success: bool = True,
    **kwargs: float,
) -> dict[str, dict[str, float | str]]:
    """Summarise each key of per-episode rows (e.g. from ``score_episode``), stating its population.

    Columns are averaged over different episodes: basic metrics over all of them, outcome rates over
    those with a known outcome, navigation time and the social metrics (M_I–M_VI) over successful
    ones (``score_episode`` leaves them NaN elsewhere). Each key's summary says which, and how many
    episodes entered its mean (``n``) out of ``n_rows``.

    Keys are processed in the order of the first row, then any new ones; one generator is shared,
    so the result depends only on ``rng`` and the rows.

    Args:
        rows: Per-episode rows; a row missing a key counts as NaN for it.
        rng: Generator for the bootstrap (default seeded, reproducible).
        require_success: The value passed to ``score_episode``: with False the social metrics'
            population is every episode.
        **kwargs: ``n_boot`` and ``confidence`` of :func:`summarize`.

    Returns:
        ``{key: {mean, std, ci_low, ci_high, n, n_rows, population}}``; ``population`` is
        ``"all"``, ``"success"`` or ``"known_outcome"`` (see ``Metric.population``), ``"unknown"``
        for keys that are not metric keys.
    """
    rng = np.random.default_rng(DEFAULT_SEED) if rng is None else rng
    keys = list(dict.fromkeys(k for row in rows for k in row))
    out: dict[str, dict[str, float | str]] = {}
    for k in keys:
        stats: dict[str, float | str] = dict(summarize([row.get(k, np.nan) for row in rows], rng, **kwargs))
        stats["n_rows"] = float(len(rows))
        stats["population"] = metric_population(k, require_success)
        out[k] = stats
    return out


def metric_population(key: str, require_success: bool) -> str:
    """The episodes a result key's mean is taken over.

    ``all``, ``success`` or ``known_outcome`` (the metric's population; a social metric counts every episode
    unless ``require_success``), or ``unknown`` for a key of no registered metric.
    """
    from socialnav.metrics.registry import _REGISTRY, load_metric_plugins, parse_key

    load_metric_plugins()

    metric = _REGISTRY.get(parse_key(key)[0])
    if metric is None:
        return "unknown"
    if metric.social and not require_success:
        return "all"
    return metric.population


def _resampling_counts(rng: np.random.Generator, n: int, n_boot: int) -> np.ndarray:
    """Bootstrap resampling weights: (n_boot, n) float counts.

    Row b says how often each of n items is drawn in n draws with replacement.
    """
    draws = rng.integers(0, n, size=(n_boot, n))
    draws += np.arange(n_boot)[:, None] * n  # each row counts into its own block
    return np.bincount(draws.ravel(), minlength=n_boot * n).reshape(n_boot, n).astype(float)


def column_stats(
    values: np.ndarray, rng: np.random.Generator, n_boot: int = 1000, confidence: float = 0.95
) -> dict[str, np.ndarray]:
    """Mean, std (ddof 1), percentile-bootstrap CI of the mean and count per column, NaNs ignored.

    One set of (n_boot, n) resampling weights W serves every column: a resampled mean is
    ``W @ v / W @ valid``, so K columns cost two matrix products instead of K bootstraps. Row b of W
    counts how often each episode is drawn in n uniform draws with replacement (multinomial(n, 1/n),
    drawn as n integers and counted, which is 10-20x faster than NumPy's multinomial sampler).

    Args:
        values: (n, K) per-episode values of K columns.
        rng: Draws the resampling weights.
        n_boot: Number of resamples.
        confidence: Coverage of the interval, in (0, 1).

    Returns:
        ``mean``, ``std``, ``ci_low``, ``ci_high``, ``n``, each of shape (K,).
    """
    n, k = values.shape
    valid = np.isfinite(values)
    count = valid.sum(axis=0)
    filled = np.where(valid, values, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = filled.sum(axis=0) / count
        var = (np.where(valid, values - mean, 0.0) ** 2).sum(axis=0) / (count - 1)
    lo = np.full(k, np.nan)
    hi = np.full(k, np.nan)
    some = count > 1
    if some.any():  # no resampling where no column has two values (e.g. the summary of one episode)
        with np.errstate(invalid="ignore", divide="ignore"):
            weights = _resampling_counts(rng, n, n_boot)
            boot = (weights @ filled) / (weights @ valid.astype(float))  # (n_boot, K): resampled means
        levels = [50 * (1 - confidence), 50 * (1 + confidence)]
        cols = np.flatnonzero(some)
        # a resample without one valid value gives NaN; only such columns need nanpercentile
        holes = np.isnan(boot[:, cols]).any(axis=0)
        q = np.empty((2, len(cols)))
        if (~holes).any():
            q[:, ~holes] = np.percentile(boot[:, cols[~holes]], levels, axis=0)
        if holes.any():
            with np.errstate(invalid="ignore"):
                q[:, holes] = np.nanpercentile(boot[:, cols[holes]], levels, axis=0)
        lo[some], hi[some] = q[0], q[1]
    single = count == 1
    lo[single] = hi[single] = mean[single]
    std = np.where(count > 1, np.sqrt(np.maximum(var, 0.0)), np.nan)
    return {"mean": mean, "std": std, "ci_low": lo, "ci_high": hi, "n": count}
