"""Scenarios drawn in a square of side W: random placement, traffic flows, square crossing.

Registered here: `random`, `parallel_traffic`, `perpendicular_traffic` and CrowdNav's
`square_crossing`. All place starts and goals separately, as CrowdSim's
``generate_square_crossing_human``: a start is redrawn while it is too close to the robot's start
or to an already placed human's start; then a goal is redrawn while it is too close to the
robot's goal or to a placed human's goal.
The traffic scenarios give each human a side σ ∈ {−1, +1}, drawn once per human (not per
attempt, as CrowdSim's sign): the start lies on side σ of the flow axis, the goal on side −σ.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from socialnav.scenarios._placement import rejection_sample
from socialnav.scenarios.base import (
    STREAM_GOAL,
    STREAM_SIDE,
    STREAM_START,
    HumanArrays,
    Scenario,
    param,
)
from socialnav.scenarios.episode_random import EpisodeRandom
from socialnav.scenarios.registry import register_scenario

__all__ = ["ParallelTraffic", "PerpendicularTraffic", "RandomPlacement", "SquareCrossing"]

_TRAFFIC_AREAS = ("half_square", "band")


@dataclass(frozen=True, kw_only=True)
class _SquareScenario(Scenario):
    """Shared placement loop; subclasses say how a start and a goal are drawn."""

    square_width: float = param(
        12.0,
        "W: side of the square centred on the origin (12 m = 1.5 x the 8 m start-goal distance)",
        unit="m",
        gt=0,
    )

    def _side(self, rng: EpisodeRandom, j: int) -> np.ndarray | None:
        """Side σ of human j [(B,)], or None for scenarios without sides."""
        return None

    def _draw_start(self, u: np.ndarray, side: np.ndarray | None) -> np.ndarray:
        """Map uniforms u [(B', 2)] in [0, 1) to a start candidate [(B', 2) m]."""
        raise NotImplementedError

    def _draw_goal(self, u: np.ndarray, side: np.ndarray | None) -> np.ndarray:
        """Map uniforms u [(B', 2)] in [0, 1) to a goal candidate [(B', 2) m]."""
        raise NotImplementedError

    def sample_humans(self, rng: EpisodeRandom, indices: np.ndarray) -> HumanArrays:
        """Place starts then goals of `n_humans` humans per episode by rejection sampling."""
        b, n, r = len(rng), self.n_humans, self.circle_radius
        radius = np.zeros((b, n))
        v_pref = np.zeros((b, n))
        # Slot 0: the robot's start (for starts) or goal (for goals); slots 1..: placed humans.
        starts = np.zeros((b, n + 1, 2))
        goals = np.zeros((b, n + 1, 2))
        starts[:, 0] = (0.0, -r)
        goals[:, 0] = (0.0, r)
        radii = np.zeros((b, n + 1))
        radii[:, 0] = self.robot_radius

        for j in range(n):
            radius[:, j], v_pref[:, j] = self.human_attributes(rng, j)
            side = self._side(rng, j)

            def draw_start(
                sub: EpisodeRandom,
                key: tuple[int, ...],
                rows: np.ndarray,
                side: np.ndarray | None = side,
            ) -> np.ndarray:
                return self._draw_start(sub.random(key, 2), None if side is None else side[rows])

            def draw_goal(
                sub: EpisodeRandom,
                key: tuple[int, ...],
                rows: np.ndarray,
                side: np.ndarray | None = side,
            ) -> np.ndarray:
                return self._draw_goal(sub.random(key, 2), None if side is None else side[rows])

            common = dict(
                j=j,
                radius=radius[:, j],
                ref_radius=radii[:, : j + 1],
                margin=self.discomfort_dist,
                max_attempts=self.max_attempts,
            )
            starts[:, j + 1] = rejection_sample(
                rng,
                draw_start,
                stream=STREAM_START,
                ref_pos=starts[:, : j + 1],
                what=f"{self.name}: start of human {j}",
                **common,
            )
            goals[:, j + 1] = rejection_sample(
                rng,
                draw_goal,
                stream=STREAM_GOAL,
                ref_pos=goals[:, : j + 1],
                what=f"{self.name}: goal of human {j}",
                **common,
            )
            radii[:, j + 1] = radius[:, j]
        return HumanArrays(start=starts[:, 1:], goal=goals[:, 1:], radius=radius, v_pref=v_pref)


@register_scenario("random")
@dataclass(frozen=True, kw_only=True)
class RandomPlacement(_SquareScenario):
    """Start and goal each uniform in the square [−W/2, W/2]² (spec scenario 2)."""

    #: The native generator computing this class's sample_humans (socialnav.scenarios.native).
    _native_kind: ClassVar[str] = "SCENARIO_RANDOM"

    def _draw_start(self, u: np.ndarray, side: np.ndarray | None) -> np.ndarray:
        return (u - 0.5) * self.square_width

    _draw_goal = _draw_start


@dataclass(frozen=True, kw_only=True)
class _TwoSidedTraffic(_SquareScenario):
    """A crowd flowing along one axis: start on side σ, goal on side −σ.

    Column `flow_axis` (1 = y, 0 = x) carries the side: σ·U(0, W/2) in `half_square` mode or
    σ·(R + U(−band_width/2, band_width/2)) in `band` mode; the other column is U(−W/2, W/2).
    """

    flow_axis: ClassVar[int] = 1

    traffic_area: str = param(
        "half_square",
        "where starts and goals lie along the flow axis: 'half_square' "
        "(sigma*U(0, W/2)) or 'band' (bands of band_width centred on +-R)",
        choices=_TRAFFIC_AREAS,
    )
    band_width: float = param(2.0, "width of the bands in 'band' mode", unit="m", gt=0)

    def cross_check(self) -> None:
        """Also refuses bands that reach past the centre line: a start and its goal on one side."""
        super().cross_check()
        if self.traffic_area == "band" and not self.band_width < 2 * self.circle_radius:
            self.refuse("band_width", f"must be < 2 x circle_radius = {2 * self.circle_radius:g} m in "
                        "'band' mode (the bands are centred on +-circle_radius, and a wider one reaches the "
                        "other side)")

    def _side(self, rng: EpisodeRandom, j: int) -> np.ndarray:
        return rng.choice_sign((STREAM_SIDE, j))

    def _place(self, u: np.ndarray, sign: np.ndarray) -> np.ndarray:
        out = np.empty_like(u)
        across = 1 - self.flow_axis
        out[:, across] = (u[:, across] - 0.5) * self.square_width
        if self.traffic_area == "band":
            depth = self.circle_radius + (u[:, self.flow_axis] - 0.5) * self.band_width
        else:
            depth = u[:, self.flow_axis] * (0.5 * self.square_width)
        out[:, self.flow_axis] = sign * depth
        return out

    def _draw_start(self, u: np.ndarray, side: np.ndarray | None) -> np.ndarray:
        assert side is not None
        return self._place(u, side)

    def _draw_goal(self, u: np.ndarray, side: np.ndarray | None) -> np.ndarray:
        assert side is not None
        return self._place(u, -side)


@register_scenario("parallel_traffic")
@dataclass(frozen=True, kw_only=True)
class ParallelTraffic(_TwoSidedTraffic):
    """Crowd flowing along ±y, with or against the robot (spec scenario 3)."""

    #: The native generator computing this class's sample_humans (socialnav.scenarios.native).
    _native_kind: ClassVar[str] = "SCENARIO_TRAFFIC"

    flow_axis: ClassVar[int] = 1


@register_scenario("perpendicular_traffic")
@dataclass(frozen=True, kw_only=True)
class PerpendicularTraffic(_TwoSidedTraffic):
    """Crowd flowing along ±x, across the robot's path (spec scenario 4).

    In `half_square` mode this is CrowdSim's square crossing at W = 12 m.
    """

    #: The native generator computing this class's sample_humans (socialnav.scenarios.native).
    _native_kind: ClassVar[str] = "SCENARIO_TRAFFIC"

    flow_axis: ClassVar[int] = 0


@register_scenario("square_crossing")
@dataclass(frozen=True, kw_only=True)
class SquareCrossing(_SquareScenario):
    """CrowdNav's square crossing (W = 10 m), kept to reproduce CrowdNav's numbers.

    px = U(0,1)·W/2·σ, py = (U(0,1) − 0.5)·W; gx = U(0,1)·W/2·(−σ), gy = (U(0,1) − 0.5)·W.
    """

    #: The native generator computing this class's sample_humans (socialnav.scenarios.native).
    _native_kind: ClassVar[str] = "SCENARIO_SQUARE_CROSSING"

    square_width: float = param(10.0, "W: side of the square (CrowdNav: 10 m)", unit="m", gt=0)

    def _side(self, rng: EpisodeRandom, j: int) -> np.ndarray:
        return rng.choice_sign((STREAM_SIDE, j))

    def _draw_start(self, u: np.ndarray, side: np.ndarray | None) -> np.ndarray:
        assert side is not None
        w = self.square_width
        return np.stack([u[:, 0] * w * 0.5 * side, (u[:, 1] - 0.5) * w], axis=1)

    def _draw_goal(self, u: np.ndarray, side: np.ndarray | None) -> np.ndarray:
        assert side is not None
        return self._draw_start(u, -side)
