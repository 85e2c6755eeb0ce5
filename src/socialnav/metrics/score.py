"""Score one episode with every registered metric, as a flat ``{key: float}`` row.

Keys follow :func:`socialnav.metrics.registry.metric_key`: ``<metric>[.<output>][@<param>=<value>,...]``
with every parameter spelled out, e.g. ``m1_personal_space.duration_s@eps=0.2,distance=clearance``.
Each metric contributes one group of keys per parameter variant it reports by default (ε ∈ {0.2, 1.2}
for M_I, τ ∈ {0.5, 1, 2} for M_II). Social metrics (M_I–M_VI) are NaN unless the outcome is success,
as in Wang et al., ARSO 2022 (arXiv 2202.01045), which computes them on successful episodes only;
basic metrics are computed on every episode. Metrics declared ``map_only`` (progress among walls:
:mod:`socialnav.metrics.progress`) are scored on episodes with a static map only; the rows of open-floor
episodes leave their keys out, so results of the original protocol keep their columns.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from typing import Any

from socialnav.metrics.registry import Metric, list_metrics
from socialnav.trajectory import Trajectory

__all__ = ["MetricError", "ParamsSpec", "UnknownOutcomeWarning", "fill_missing_keys", "score_episode",
           "score_keys"]


class UnknownOutcomeWarning(UserWarning):
    """Social metrics were requested on an episode whose outcome is unknown: they are NaN."""


ParamsSpec = Mapping[str, Mapping[str, Any] | Sequence[Mapping[str, Any]]]
"""Per metric name: one parameter override (dict) or several (list of dicts, one key group each)."""


def _variants(metric: Metric, params: ParamsSpec | None) -> list[dict[str, Any]]:
    spec = (params or {}).get(metric.name)
    if spec is None:
        return [metric.resolve(v) for v in metric.variants]
    if isinstance(spec, Mapping):
        return [metric.resolve(spec)]
    return [metric.resolve(v) for v in spec]


def _check_names(params: ParamsSpec | None) -> None:
    if params is not None and not isinstance(params, Mapping):
        raise TypeError(f"params must map metric names to parameter dicts, e.g. {{'m1_personal_space': "
                        f"{{'eps': 0.5}}}}, got a {type(params).__name__}")
    known = {m.name for m in list_metrics()}
    unknown = set(params or {}) - known
    if unknown:
        raise KeyError(f"unknown metric(s) {sorted(unknown)} in params; valid names: {sorted(known)}")
    for name, spec in (params or {}).items():
        if spec is None or isinstance(spec, Mapping):
            continue
        if isinstance(spec, str) or not isinstance(spec, Sequence) or not spec or not all(
                isinstance(v, Mapping) for v in spec):
            raise TypeError(f"params[{name!r}] must be a dict of parameters or a non-empty list of them (one "
                            f"result per dict), got {spec!r}")


def score_keys(params: ParamsSpec | None = None, *, static_map: bool = False) -> list[str]:
    """The keys :func:`score_episode` returns for these params, in order (for table columns).

    By default those of an episode without a static map (an open floor); ``static_map=True`` gives those
    of an episode with one, which add the keys of the ``map_only`` metrics.
    """
    _check_names(params)
    return [key for m in list_metrics() if static_map or not m.map_only
            for v in _variants(m, params) for key in m.keys(v)]


def fill_missing_keys(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Rows that all have every key any of them has, NaN where a row lacked one.

    Episodes with and without a static map have different keys (``map_only`` metrics); a table of
    rows (a Parquet chunk, a printout) takes its columns from its first row. Rows that already share
    their keys come back as they are (the same objects).

    Args:
        rows: Result rows (score rows with identifiers).

    Returns:
        The rows, each with the keys of the row with the most keys first, in its order, then any other
        key in order of first appearance.
    """
    if len({frozenset(r) for r in rows}) <= 1:
        return list(rows)
    longest: dict[str, Any] = max(rows, key=len)
    order = dict.fromkeys(longest)
    for row in rows:
        order.update(dict.fromkeys(k for k in row if k not in order))
    return [{k: row.get(k, float("nan")) for k in order} for row in rows]


def score_episode(
    traj: Trajectory, params: ParamsSpec | None = None, *, require_success: bool = True
) -> dict[str, float]:
    """Compute every registered metric on one episode.

    Args:
        traj: The episode.
        params: Optional overrides per metric name, e.g. ``{"m1_personal_space": {"distance":
            "centre"}}`` (one setting, merged over the defaults) or ``{"m2_projected_path": [{"tau":
            1.0, "anchor": "front"}]}`` (one key group per setting). Metrics not named keep their
            default variants.
        require_success: If True (default, the paper's protocol), social metrics are NaN unless
            ``traj.outcome == "success"``. Set False to score logs whose outcome is ``unknown``.

    Returns:
        ``{flat key: value}`` with the same keys for every episode with a static map, and for every
        episode without one (see :func:`score_keys`; ``map_only`` metrics are left out there).

    Raises:
        MetricError: A metric raised (its name and the episode are said, its exception chained).

    Warns:
        UnknownOutcomeWarning: ``require_success`` is True and the outcome is ``unknown``, so every
            social metric is NaN (a log without outcome: pass ``require_success=False``).
    """
    plan = _plan(params)  # unknown metric names raise here, before any work
    row: dict[str, float] = {}
    gated = require_success and traj.outcome != "success"
    if gated and traj.outcome == "unknown":
        warnings.warn("episode outcome is 'unknown': social metrics (M_I-M_VI) are NaN because they are "
                      "computed on successful episodes only; pass require_success=False (CLI: "
                      "--all-episodes) or give the outcome", UnknownOutcomeWarning, stacklevel=2)
    no_map = traj.static_map is None
    for metric, variant, keys in plan:
        if no_map and metric.map_only:
            continue
        if metric.social and gated:
            row.update(dict.fromkeys(keys, float("nan")))
            continue
        try:
            values = metric.fn(traj, **variant)
            row.update({k: float(values[out]) for k, out in zip(keys, metric.outputs, strict=True)})
        except Exception as exc:  # a metric of one's own that fails: said with the metric and the episode
            episode = traj.settings.get("episode", "?")
            raise MetricError(f"metric {metric.name!r} failed on episode {episode!r}: {type(exc).__name__}: "
                              f"{exc}") from exc
    return row


class MetricError(RuntimeError):
    """A metric raised while scoring an episode (the metric and the episode are named)."""


_DEFAULT_PLAN: tuple[tuple[int, ...], list[tuple[Metric, dict[str, Any], list[str]]]] | None = None


def _plan(params: ParamsSpec | None) -> list[tuple[Metric, dict[str, Any], list[str]]]:
    """(metric, resolved parameters, keys) of every call, in row order.

    Without overrides it is built once per set of registered metrics: a file of 10 000 episodes asks for
    it 10 000 times.
    """
    global _DEFAULT_PLAN
    metrics = list_metrics()
    if params is None:
        ident = tuple(id(m) for m in metrics)
        if _DEFAULT_PLAN is None or _DEFAULT_PLAN[0] != ident:
            _DEFAULT_PLAN = (ident, _build_plan(metrics, None))
        return _DEFAULT_PLAN[1]
    _check_names(params)
    return _build_plan(metrics, params)


def _build_plan(metrics: list[Metric], params: ParamsSpec | None
                ) -> list[tuple[Metric, dict[str, Any], list[str]]]:
    return [(m, v, m.keys(v)) for m in metrics for v in _variants(m, params)]
