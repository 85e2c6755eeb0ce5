"""Single-human scenarios for side preference (M_VI): `passing`, `overtaking`, `crossing`.

Episode ``index`` uses lateral offset o_i with i = index % n_offsets and repeat r =
index // n_offsets, so the split holds n_offsets · repeats episodes. Offsets are the grid
o_i = −s + i·2s/(n_offsets − 1), s = `offset_span` (default r_robot + r_human = 0.6 m: the offsets
at which a straight-walking robot and human just touch, the range over which a side must be
chosen). Repeat r = 0 is the exact grid; r ≥ 1 adds seeded jitter: offset ± `offset_jitter`
(default half a grid spacing) on start and goal alike, and the start moved by ±`start_jitter` on
each axis. No rejection is needed with one human.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from socialnav.scenarios.base import STREAM_JITTER, HumanArrays, Scenario, param
from socialnav.scenarios.episode_random import EpisodeRandom
from socialnav.scenarios.registry import register_scenario

__all__ = ["Crossing", "Overtaking", "Passing"]


@dataclass(frozen=True, kw_only=True)
class _SingleHuman(Scenario):
    """Shared offset grid and jitter; subclasses map offsets to start and goal."""

    fixed_n_humans = True

    n_humans: int = param(1, "humans per episode (always 1 here)", ge=1)
    n_offsets: int = param(20, "lateral offsets on the grid, endpoints included", ge=2)
    offset_span: float | None = param(
        None, "s: offsets span [-s, s]; None = robot_radius + human_radius", unit="m", gt=0
    )
    repeats: int = param(1, "k: episodes per offset (repeat 0 exact, 1..k-1 jittered)", ge=1)
    offset_jitter: float | None = param(
        None,
        "jitter of the offset for repeats >= 1: U(-j, j); None = half a grid spacing",
        unit="m",
        ge=0,
    )
    start_jitter: float = param(
        0.1, "jitter of the start on each axis for repeats >= 1: U(-j, j)", unit="m", ge=0
    )

    def __post_init__(self) -> None:
        """Validate settings; randomised attributes would break the designed geometry."""
        super().__post_init__()
        if self.randomize_attributes:
            raise ValueError(
                f"{type(self).__name__}.randomize_attributes must be False (the offsets and "
                f"speeds are the experiment's design), got {self.randomize_attributes!r}"
            )
        self._check_start_clearance()

    def _check_start_clearance(self) -> None:
        """Refuses settings whose human can start touching the robot: the episode would end at once.

        These scenarios place the human by design, with no rejection step; the check takes the exact
        grid and, with repeats, the largest jitter towards the robot.
        """
        start, _ = self._line(self.offsets)
        robot_start, _ = self.robot_endpoints()
        gap = float(np.min(np.linalg.norm(start - np.asarray(robot_start, dtype=float), axis=1)))
        if self.repeats > 1:
            oj = self.span / (self.n_offsets - 1) if self.offset_jitter is None else self.offset_jitter
            gap -= oj + math.sqrt(2.0) * self.start_jitter
        need = self.robot_radius + self.human_radius
        if not gap > need:
            raise ValueError(
                f"{type(self).__name__}: the human can start {max(gap, 0.0):.3g} m from the robot's centre, "
                f"within their radii ({need:g} m): the episode would end in a collision at once "
                f"(check circle_radius {self.circle_radius:g}{self._clearance_settings()}, start_jitter, "
                "offset_jitter)"
            )

    def _clearance_settings(self) -> str:
        return ""

    @property
    def span(self) -> float:
        """Half-span s of the offset grid [m]."""
        if self.offset_span is not None:
            return self.offset_span
        return self.robot_radius + self.human_radius

    @property
    def offsets(self) -> np.ndarray:
        """The exact offset grid [(n_offsets,) m], endpoints ±s."""
        return np.linspace(-self.span, self.span, self.n_offsets)

    @property
    def n_episodes(self) -> int:
        """n_offsets · repeats."""
        return self.n_offsets * self.repeats

    def _human_v_pref(self) -> float:
        return self.human_v_pref

    def _line(self, offset: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Start and goal [(B, 2) m] for lateral offsets [(B,) m]."""
        raise NotImplementedError

    def sample_humans(self, rng: EpisodeRandom, indices: np.ndarray) -> HumanArrays:
        """Lay the human on the offset grid (plus jitter for repeats >= 1)."""
        if indices.size and indices.max() >= self.n_episodes:
            raise ValueError(
                f"{self.name} has {self.n_episodes} episodes (n_offsets={self.n_offsets} x "
                f"repeats={self.repeats}); got index {int(indices.max())}"
            )
        b = indices.shape[0]
        offset = self.offsets[indices % self.n_offsets]
        jittered = indices >= self.n_offsets
        oj = self.offset_jitter
        if oj is None:
            oj = self.span / (self.n_offsets - 1)  # half of the spacing 2s/(n-1)
        # Draw for every row and keep them only for r >= 1, so the draws stay keyed by seed only.
        offset = offset + np.where(jittered, rng.uniform((STREAM_JITTER, 0), -oj, oj), 0.0)
        start, goal = self._line(offset)
        dstart = rng.uniform((STREAM_JITTER, 1), -self.start_jitter, self.start_jitter, 2)
        start = start + np.where(jittered[:, None], dstart, 0.0)
        return HumanArrays(
            start=start[:, None, :],
            goal=goal[:, None, :],
            radius=np.full((b, 1), float(self.human_radius)),
            v_pref=np.full((b, 1), float(self._human_v_pref())),
        )


@register_scenario("passing")
@dataclass(frozen=True, kw_only=True)
class Passing(_SingleHuman):
    """Head-on: human start (o, +R), goal (o, −R) (spec scenario 5)."""

    def _line(self, offset: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r = np.full_like(offset, self.circle_radius)
        return np.stack([offset, r], axis=1), np.stack([offset, -r], axis=1)


@register_scenario("overtaking")
@dataclass(frozen=True, kw_only=True)
class Overtaking(_SingleHuman):
    """Slower human ahead, same direction: start (o, −R + gap), goal (o, R + gap) (scenario 6).

    Its v_pref is speed_ratio · robot_v_pref, so with the defaults a robot driving straight at
    full speed catches up at y = −R + gap/(1 − speed_ratio) = 0, the origin.
    """

    gap: float = param(2.0, "head start of the human along +y", unit="m", gt=0)
    speed_ratio: float = param(0.5, "human v_pref / robot v_pref", gt=0)

    def cross_check(self) -> None:
        """Also refuses a human at least as fast as the robot: it would never be overtaken."""
        super().cross_check()
        if not self.speed_ratio < 1:
            self.refuse("speed_ratio",
                        "must be < 1 (a slower human ahead, caught at -R + gap/(1 - speed_ratio))")

    def _clearance_settings(self) -> str:
        return f", gap {self.gap:g}"

    def _human_v_pref(self) -> float:
        return self.speed_ratio * self.robot_v_pref

    def _line(self, offset: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r, g = self.circle_radius, self.gap
        return (
            np.stack([offset, np.full_like(offset, -r + g)], axis=1),
            np.stack([offset, np.full_like(offset, r + g)], axis=1),
        )


@register_scenario("crossing")
@dataclass(frozen=True, kw_only=True)
class Crossing(_SingleHuman):
    """Human from the robot's left walking right: start (−R, o), goal (+R, o) (scenario 7)."""

    def _line(self, offset: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r = np.full_like(offset, self.circle_radius)
        return np.stack([-r, offset], axis=1), np.stack([r, offset], axis=1)
