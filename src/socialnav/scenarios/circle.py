"""`circle_crossing`: humans start around a circle and walk to the antipode (CrowdNav's plaza).

Follows CrowdSim's ``generate_circle_crossing_human``: angle θ ~ U[0, 2π), start
R·(cos θ, sin θ) + noise U(−0.5, 0.5)·v_pref on x and y, goal = −start. The candidate start is
tested against every placed agent's position AND goal (robot included), which, since goals are
antipodes, also keeps the goal clear of every other start and goal.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from socialnav.scenarios._placement import rejection_sample
from socialnav.scenarios.base import STREAM_START, HumanArrays, Scenario, param
from socialnav.scenarios.episode_random import EpisodeRandom
from socialnav.scenarios.registry import register_scenario

__all__ = ["CircleCrossing"]


@register_scenario("circle_crossing")
@dataclass(frozen=True, kw_only=True)
class CircleCrossing(Scenario):
    """Humans on a circle of radius R crossing to the opposite side (spec scenario 1).

    Each attempt at human j draws (θ, noise_x, noise_y) with key (STREAM_START, j, attempt).
    """

    #: The native generator computing this class's sample_humans (socialnav.scenarios.native).
    _native_kind: ClassVar[str] = "SCENARIO_CIRCLE"

    start_noise: float = param(
        0.5,
        "half-width of the uniform start noise per axis, as a time: noise [m] = start_noise x v_pref",
        unit="s",
        ge=0,
    )

    def sample_humans(self, rng: EpisodeRandom, indices: np.ndarray) -> HumanArrays:
        """Place `n_humans` humans per episode by rejection sampling (see module docstring)."""
        b, n, r_circle = len(rng), self.n_humans, self.circle_radius
        start = np.zeros((b, n, 2))
        radius = np.zeros((b, n))
        v_pref = np.zeros((b, n))
        # References: robot start, robot goal, then the starts and goals of placed humans.
        ref_pos = np.zeros((b, 2 + 2 * n, 2))
        ref_pos[:, 0] = (0.0, -r_circle)
        ref_pos[:, 1] = (0.0, r_circle)
        ref_rad = np.zeros((b, 2 + 2 * n))
        ref_rad[:, :2] = self.robot_radius

        for j in range(n):
            radius[:, j], v_pref[:, j] = self.human_attributes(rng, j)
            vp = v_pref[:, j]

            def draw(
                sub: EpisodeRandom, key: tuple[int, ...], rows: np.ndarray, vp: np.ndarray = vp
            ) -> np.ndarray:
                u = sub.random(key, 3)
                angle = u[:, 0] * (2.0 * np.pi)
                noise = (2.0 * u[:, 1:] - 1.0) * (self.start_noise * vp[rows, None])
                return r_circle * np.stack([np.cos(angle), np.sin(angle)], axis=1) + noise

            m = 2 + 2 * j
            start[:, j] = rejection_sample(
                rng,
                draw,
                stream=STREAM_START,
                j=j,
                radius=radius[:, j],
                ref_pos=ref_pos[:, :m],
                ref_radius=ref_rad[:, :m],
                margin=self.discomfort_dist,
                max_attempts=self.max_attempts,
                what=f"{self.name}: start of human {j}",
            )
            ref_pos[:, m] = start[:, j]
            ref_pos[:, m + 1] = -start[:, j]
            ref_rad[:, m : m + 2] = radius[:, j, None]
        return HumanArrays(start=start, goal=-start, radius=radius, v_pref=v_pref)
