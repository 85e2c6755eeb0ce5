"""Metric registry: every metric declares its name, units, direction and parameters.

Metrics register themselves where they are defined (``@register_metric(...)``), so there is no
central list to keep in sync. Another package adds metrics through the entry-point group
``socialnav.metrics``: an entry point names a module whose import registers them, loaded on the first
lookup of the registry (in every process that scores), so ``socialnav evaluate`` and ``socialnav
metrics`` report them beside the built-in ones. :func:`socialnav.metrics.score.score_episode` runs
every registered metric and flattens the results into keys built by :func:`metric_key`:

    ``<metric>[.<output>][@<param>=<value>,...]``

The output part is omitted for single-valued metrics (output ``value``) and the parameter part when
the metric has no parameters; all parameters are listed, in declaration order, so that values
computed under different settings never share a key. Examples: ``success``,
``m1_personal_space.duration_s@eps=0.2,distance=clearance``, ``m4_jerk.mean_sq``.

One exception keeps published keys stable: a parameter added to a metric after its keys appeared in
result files is declared *quiet* (``quiet_parameters``) and is listed only when it differs from its
default. ``m4_jerk.mean_sq`` is M_IV as it always was; ``m4_jerk.mean_sq@dt_power=2`` is a variant.

Another keeps the result files of open floors as they were: a metric declared ``map_only`` is scored on
episodes with a static map only, and rows of episodes without one leave its keys out (not NaN: a new
column would change every open-floor results file byte for byte).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

__all__ = [
    "ENTRY_POINT_GROUP",
    "Metric",
    "get_metric",
    "list_metrics",
    "load_metric_plugins",
    "metric_key",
    "parse_key",
    "register_metric",
]

Direction = Literal["lower", "higher", "none"]
MetricFn = Callable[..., dict[str, float]]

WANG2022 = (
    "Wang, Chan, Carreno-Medrano, Cosgun, Croft, 'Metrics for Evaluating Social Conformity of Crowd "
    "Navigation Algorithms', ARSO 2022 (arXiv 2202.01045)"
)
JIN2020 = "Jin et al., 'Mapless Navigation among Dynamics with Social-safety-awareness', ICRA 2020"

_REGISTRY: dict[str, Metric] = {}

POPULATIONS: tuple[str, ...] = ("all", "success", "known_outcome")
"""Which episodes a metric's mean is over (see :attr:`Metric.population`)."""


@dataclass(frozen=True)
class Metric:
    """A registered metric.

    Attributes:
        name: Short unique name, the first part of every flat key.
        unit: Unit of the primary (first) output.
        direction: "lower" or "higher" is better, or "none" (descriptive only).
        parameters: Default parameter values, passed as keyword arguments to ``fn``.
        description: One-line description.
        reference: Paper and equation/section implemented.
        outputs: Output name -> unit, in reporting order.
        variants: Parameter overrides reported by default (e.g. ε = 0.2 and 1.2); each is merged
            over ``parameters``. One empty override means "defaults only".
        social: Only meaningful on successful episodes (NaN otherwise in ``score_episode``).
        population: Episodes whose values enter a mean: ``"all"``, ``"success"`` (social metrics and
            navigation time) or ``"known_outcome"`` (outcome rates; NaN when the outcome is unknown).
        quiet_parameters: Parameters listed in a key only when they differ from their default
            (parameters added after the metric's keys were published; see the module docstring).
        positive_parameters: Numeric parameters that must be > 0, not only >= 0 (a zero cap or
            horizon makes every value 0, silently).
        map_only: Scored by :func:`~socialnav.metrics.score.score_episode` only on episodes with a static
            map; the rows of the others leave its keys out (see the module docstring). Calling the metric
            itself computes it on any trajectory.
        fn: ``fn(traj, **params) -> {output: value}``.
    """

    name: str
    unit: str
    direction: Direction
    parameters: Mapping[str, Any]
    description: str
    reference: str
    outputs: Mapping[str, str]
    variants: tuple[Mapping[str, Any], ...] = ({},)
    social: bool = False
    population: str = "all"
    quiet_parameters: frozenset[str] = frozenset()
    positive_parameters: frozenset[str] = frozenset()
    map_only: bool = False
    fn: MetricFn = field(default=lambda traj: {}, repr=False)

    def resolve(self, overrides: Mapping[str, Any] | None = None) -> dict[str, Any]:
        """Defaults merged with ``overrides``; unknown parameter names raise a KeyError."""
        overrides = dict(overrides or {})
        unknown = set(overrides) - set(self.parameters)
        if unknown:
            raise KeyError(f"metric {self.name!r}: unknown parameter(s) {sorted(unknown)}; "
                           f"valid: {list(self.parameters)}")
        for key, value in overrides.items():
            default = self.parameters[key]
            # the numeric parameters are magnitudes (distances, durations, speeds, thresholds)
            number = isinstance(value, int | float | np.integer | np.floating) and not isinstance(
                value, bool | np.bool_)
            if isinstance(default, int | float) and not isinstance(default, bool) and (
                    not number or not math.isfinite(value) or value < 0):
                raise ValueError(f"metric {self.name!r}: parameter {key} must be a finite number >= 0, got "
                                 f"{value!r}")
            if key in self.positive_parameters and not value > 0:
                raise ValueError(f"metric {self.name!r}: parameter {key} must be > 0, got {value!r}")
        return {**self.parameters, **overrides}

    def __call__(self, traj: Any, **params: Any) -> dict[str, float]:
        """Compute the metric's outputs on one trajectory with resolved parameters."""
        return self.fn(traj, **self.resolve(params))

    def keys(self, params: Mapping[str, Any] | None = None) -> list[str]:
        """Flat keys of this metric's outputs for one parameter setting (see module docstring)."""
        resolved = self.resolve(params)
        # Scoring asks for the same few keys once per episode: format each setting only once.
        cache_key = tuple((k, repr(v)) for k, v in resolved.items())
        cached = _KEY_CACHE.get((self.name, cache_key))
        if cached is None:
            cached = [_format_key(self.name, out, self._key_params(resolved)) for out in self.outputs]
            _KEY_CACHE[(self.name, cache_key)] = cached
        return list(cached)


    def _key_params(self, resolved: Mapping[str, Any]) -> dict[str, Any]:
        """The parameters a key lists: all of them, except quiet ones at their default."""
        return {k: v for k, v in resolved.items()
                if k not in self.quiet_parameters or _format_value(v) != _format_value(self.parameters[k])}


_KEY_CACHE: dict[tuple[str, tuple], list[str]] = {}


def _format_value(value: Any) -> str:
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, (float, np.floating)):
        return np.format_float_positional(float(value), trim="-")
    return str(value)


def metric_key(name: str, output: str = "value", params: Mapping[str, Any] | None = None) -> str:
    """Build the flat key ``<name>[.<output>][@k=v,...]`` that :func:`score_episode` rows use.

    Parameters are resolved against the registered metric: omitted ones take their defaults and all
    (quiet parameters at their default aside) are listed in declaration order, so
    ``metric_key("m2_projected_path", "count", {"tau": 1.0})``
    is ``m2_projected_path.count@tau=1,anchor=rear``, exactly the row's key.

    Args:
        name: Registered metric name.
        output: Output name; ``"value"`` (single-valued metrics) is omitted from the key.
        params: Parameter overrides (any subset of the metric's parameters).

    Returns:
        The key.

    Raises:
        KeyError: Unknown metric, output or parameter name (the message lists the valid ones).
    """
    metric = get_metric(name)
    if output not in metric.outputs:
        raise KeyError(f"metric {name!r} has no output {output!r}; outputs: {list(metric.outputs)}")
    return _format_key(name, output, metric._key_params(metric.resolve(params)))


def _format_key(name: str, output: str, params: Mapping[str, Any]) -> str:
    key = name if output == "value" else f"{name}.{output}"
    if params:
        key += "@" + ",".join(f"{k}={_format_value(v)}" for k, v in params.items())
    return key


def parse_key(key: str) -> tuple[str, str, dict[str, str]]:
    """Split a flat key into (metric name, output, parameters as strings); inverse of metric_key."""
    head, _, tail = key.partition("@")
    name, _, output = head.partition(".")
    params = dict(item.split("=", 1) for item in tail.split(",")) if tail else {}
    return name, output or "value", params


def register_metric(
    name: str,
    *,
    unit: str,
    direction: Direction,
    outputs: Mapping[str, str],
    reference: str,
    parameters: Mapping[str, Any] | None = None,
    variants: tuple[Mapping[str, Any], ...] = ({},),
    social: bool = False,
    description: str | None = None,
    population: str | None = None,
    quiet_parameters: tuple[str, ...] = (),
    positive_parameters: tuple[str, ...] = (),
    map_only: bool = False,
) -> Callable[[MetricFn], MetricFn]:
    """Decorator registering ``fn(traj, **params) -> {output: value}`` as a metric.

    The function is returned unchanged so it stays callable directly; the description defaults to
    the first line of its docstring.

    Raises:
        ValueError: The name is taken or the direction is not lower/higher/none.
    """
    if direction not in ("lower", "higher", "none"):
        raise ValueError(f"metric {name!r}: direction must be lower/higher/none, got {direction!r}")
    population = population or ("success" if social else "all")
    if population not in POPULATIONS:
        raise ValueError(f"metric {name!r}: population must be one of {POPULATIONS}, got {population!r}")

    unknown_quiet = set(quiet_parameters) - set(parameters or {})
    if unknown_quiet:
        raise ValueError(f"metric {name!r}: quiet parameter(s) {sorted(unknown_quiet)} are not parameters")

    def wrap(fn: MetricFn) -> MetricFn:
        if name in _REGISTRY:
            raise ValueError(f"metric {name!r} is already registered")
        metric = Metric(
            name=name, unit=unit, direction=direction, parameters=dict(parameters or {}),
            description=description or (fn.__doc__ or "").strip().splitlines()[0],
            reference=reference, outputs=dict(outputs), variants=tuple(variants), social=social,
            population=population, quiet_parameters=frozenset(quiet_parameters),
            positive_parameters=frozenset(positive_parameters), map_only=map_only, fn=fn,
        )
        for variant in metric.variants:
            metric.resolve(variant)  # fail at import time on a misspelt variant parameter
        _REGISTRY[name] = metric
        return fn

    return wrap


#: The entry-point group of metric plugins (docs/extending.md, "A metric").
ENTRY_POINT_GROUP = "socialnav.metrics"
_plugins_loaded = False


def load_metric_plugins() -> None:
    """Imports every module the ``socialnav.metrics`` entry points name, once per process.

    Importing a module registers its metrics; one that fails to import is a RuntimeWarning, never an error.
    """
    global _plugins_loaded
    if _plugins_loaded:
        return
    _plugins_loaded = True
    from socialnav.plugins import load_entry_points

    for _entry_point, _module in load_entry_points(ENTRY_POINT_GROUP, "metric"):
        pass  # importing the module ran its @register_metric decorators


def list_metrics() -> list[Metric]:
    """All registered metrics, in registration order (the plugins' after the built-in ones)."""
    load_metric_plugins()
    return list(_REGISTRY.values())


def get_metric(name: str) -> Metric:
    """The metric registered under ``name``.

    Raises:
        KeyError: Unknown name; the message lists the valid names.
    """
    load_metric_plugins()
    try:
        return _REGISTRY[name]
    except KeyError:
        raise KeyError(f"unknown metric {name!r}; valid names: {sorted(_REGISTRY)}") from None
