"""Rejection sampling of human positions, vectorised over episodes (CrowdSim's rule).

CrowdSim places humans one at a time and redraws a candidate position while it lies closer than
``r_candidate + r_other + discomfort_dist`` to any reference point (the robot, humans already
placed). Here the loop runs over attempts, and each attempt draws for all episodes that still
need a position at once. Attempt a of human j is keyed (stream, j, a), so an episode gets the
same candidates, hence the same result, whatever else is in its batch.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from socialnav.scenarios.episode_random import EpisodeRandom

__all__ = ["ScenarioGenerationError", "rejection_sample"]

#: draw(rng_rows, key, rows) -> candidates [(len(rows), 2) m]; rng_rows covers exactly `rows`.
DrawFn = Callable[[EpisodeRandom, tuple[int, ...], np.ndarray], np.ndarray]
#: What to change when a human cannot be placed (the default advice of a failed placement).
CROWDED = ("the scene is too crowded for the space, radii and discomfort_dist (reduce n_humans or enlarge "
           "the area)")


class ScenarioGenerationError(RuntimeError):
    """A scene could not be generated (e.g. too many humans for the space and clearances)."""


def rejection_sample(
    rng: EpisodeRandom,
    draw: DrawFn,
    *,
    stream: int,
    j: int,
    radius: np.ndarray,
    ref_pos: np.ndarray,
    ref_radius: np.ndarray,
    margin: float,
    max_attempts: int,
    what: str,
    accept: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
    clear_of: str | None = None,
    advice: str = CROWDED,
) -> np.ndarray:
    """Draw a position per episode until it clears every reference disc.

    A candidate p is accepted when ``|p - ref_pos[k]| >= radius + ref_radius[k] + margin`` for
    every reference k (CrowdSim rejects ``norm < min_dist``).

    Args:
        rng: Random source over all B episodes.
        draw: Candidate generator, called with the rows still to be placed.
        stream: First word of the draw keys (which quantity is drawn).
        j: Human index (second key word); the attempt number is the third.
        radius: Radius of the human being placed [(B,) m].
        ref_pos: Positions to keep clear of [(B, M, 2) m].
        ref_radius: Their radii [(B, M) m].
        margin: Extra clearance (discomfort distance) [m].
        max_attempts: Attempts before giving up.
        what: Name of the quantity for error messages (e.g. "circle_crossing start of human 3").
        accept: Optional further test ``accept(rows, candidates) -> (len(rows),) bool`` (e.g. clear of
            the walls); a candidate must pass it too.
        clear_of: What a position must clear, for the error (default: the other agents, and the walls
            with ``accept``).
        advice: What the error tells the user to change (default: fewer humans or a larger area).

    Returns:
        Accepted positions [(B, 2) m].

    Raises:
        ScenarioGenerationError: Some episode found no valid position within max_attempts.
    """
    b = len(rng)
    out = np.empty((b, 2))
    rows = np.arange(b)
    # Squared thresholds avoid a sqrt per pair; computed once, sliced per attempt.
    min_dist = radius[:, None] + ref_radius + margin
    min_d2 = min_dist * min_dist
    for attempt in range(max_attempts):
        if rows.size == 0:
            return out
        sub = rng if rows.size == b else rng.take(rows)
        cand = draw(sub, (stream, j, attempt), rows)
        diff = cand[:, None, :] - ref_pos[rows]
        d2 = np.einsum("bmk,bmk->bm", diff, diff)
        ok = np.all(d2 >= min_d2[rows], axis=1)
        if accept is not None:
            ok &= accept(rows, cand)
        out[rows[ok]] = cand[ok]
        rows = rows[~ok]
    if rows.size == 0:
        return out
    raise ScenarioGenerationError(failure_message(
        what, max_attempts, rng.seeds[rows], walls=accept is not None, clear_of=clear_of, advice=advice))


def failure_message(what: str, max_attempts: int, seeds: np.ndarray, walls: bool = False, *,
                    clear_of: str | None = None, advice: str = CROWDED) -> str:
    """The error of a placement that failed in the episodes of ``seeds`` (Python and native paths)."""
    shown = ", ".join(str(s) for s in seeds[:5]) + (", ..." if seeds.size > 5 else "")
    if clear_of is None:
        clear_of = "the other agents and the walls" if walls else "the other agents"
    return (
        f"{what}: no position clear of {clear_of} after {max_attempts} attempts in "
        f"{seeds.size} episode(s) (seeds {shown}); {advice}"
    )
