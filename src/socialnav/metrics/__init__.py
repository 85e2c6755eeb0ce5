"""Social-conformity metrics: pure NumPy functions of a :class:`socialnav.trajectory.Trajectory`.

Importing this package registers every metric (basic, M_I–M_VI, obstacle clearance, progress among
walls) and imports NumPy only (the route distances of :mod:`~socialnav.metrics.progress` import the
compiled core when a map is scored). Score one
episode with :func:`score_episode`; aggregate with :func:`summarize`. See ``docs/metrics.md``.
"""

from socialnav.metrics import basic, comfort, naturalness, sociability  # noqa: F401  (registration)

# isort: split
# registered after the human metrics, so that their columns come first in every table
# (progress: map_only, rows of open-floor episodes leave its keys out)
from socialnav.metrics import obstacles, progress  # noqa: F401
from socialnav.metrics.aggregate import summarize, summarize_rows
from socialnav.metrics.naturalness import WalkingSpeedWarning, walking_speed_note
from socialnav.metrics.registry import (
    Metric,
    get_metric,
    list_metrics,
    metric_key,
    parse_key,
    register_metric,
)
from socialnav.metrics.score import UnknownOutcomeWarning, score_episode, score_keys
from socialnav.metrics.sociability import (
    SIDE_CASES,
    side_case,
    side_case_of_row,
    side_preference,
    summarize_side_preference,
)

__all__ = [
    "SIDE_CASES",
    "Metric",
    "UnknownOutcomeWarning",
    "WalkingSpeedWarning",
    "get_metric",
    "list_metrics",
    "metric_key",
    "parse_key",
    "register_metric",
    "score_episode",
    "score_keys",
    "side_case",
    "side_case_of_row",
    "side_preference",
    "summarize",
    "summarize_rows",
    "summarize_side_preference",
    "walking_speed_note",
]
