"""Francis et al.'s circle crossing with static obstacles: square pillars drawn per episode.

The one scenario after Francis et al. 2025, Fig. 7 (x) whose map changes from episode to episode
(the fixed layouts are in ``francis.py``, whose conventions it shares: ``discomfort_dist`` between
placed agents, pillars and walls; R = ``circle_radius``; the robot walks from (0, −R) towards +y).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from socialnav.maps.static_map import StaticMap
from socialnav.scenarios._placement import rejection_sample
from socialnav.scenarios.base import STREAM_START, HumanArrays, param
from socialnav.scenarios.episode_random import EpisodeRandom
from socialnav.scenarios.registry import register_scenario
from socialnav.scenarios.walls import STREAM_OBSTACLES, Flow, WalledScenario

__all__ = ["CircleCrossingObstacles"]


@register_scenario("circle_crossing_obstacles")
@dataclass(frozen=True, kw_only=True)
class CircleCrossingObstacles(WalledScenario):
    """Francis (x) with static obstacles: circle crossing around square pillars.

    As social-jym and Social-Navigation-PyEnvs have it: humans cross a circle of radius R to the antipode of
    their start (CrowdSim's rule, start noise ±0.5 m) around square pillars drawn per episode inside radius
    R/2.

    Pillar p: centre uniform in the disc of radius ``obstacle_area``·R, random rotation, redrawn while
    closer than 2·circumradius + 2·robot_radius + discomfort_dist to a placed pillar, so that the
    robot fits between any two, or closer than circumradius + robot_radius + discomfort_dist to the
    robot's start or goal (the clearance a fixed layout must leave them).
    """

    n_humans: int = param(5, "humans per episode", ge=0)
    n_obstacles: int = param(3, "square pillars per episode", ge=0)
    obstacle_size: float = param(0.6, "side of a pillar", unit="m", gt=0)
    obstacle_area: float = param(0.5, "pillars' centres lie within this fraction of R", gt=0)

    @property
    def layout(self) -> StaticMap | None:
        """None: the pillars are drawn per episode (:meth:`maps_per_episode`)."""
        return None  # drawn per episode

    @property
    def max_obstacle_edges(self) -> int:
        """Four edges per square pillar."""
        return 4 * self.n_obstacles

    def maps_per_episode(self, rng: EpisodeRandom, indices: np.ndarray) -> tuple[StaticMap, ...]:
        """Square pillars drawn per episode inside radius ``obstacle_area`` · R, clear of each other.

        Args:
            rng: The episodes' random streams.
            indices: (B,) episode indices.

        Returns:
            One StaticMap per episode (empty ones where ``n_obstacles`` is 0).
        """
        b, p = len(rng), self.n_obstacles
        if p == 0:
            return (StaticMap(),) * b
        reach = self.obstacle_area * self.circle_radius
        circum = self.obstacle_size / np.sqrt(2.0)
        centres = np.zeros((b, p, 2))
        angles = rng.uniform((STREAM_OBSTACLES, 0), 0.0, np.pi / 2, p)  # a square repeats every 90 deg

        def draw(sub: EpisodeRandom, key: tuple[int, ...], rows: np.ndarray) -> np.ndarray:
            u = sub.random(key, 2)
            rad, ang = reach * np.sqrt(u[:, 0]), 2 * np.pi * u[:, 1]
            return np.stack([rad * np.cos(ang), rad * np.sin(ang)], axis=1)

        robot = np.array(self.robot_endpoints())
        robot_clearance = circum + self.robot_radius + self.discomfort_dist

        def clear_of_robot(rows: np.ndarray, points: np.ndarray) -> np.ndarray:
            return np.all(np.linalg.norm(points[:, None] - robot[None], axis=-1) >= robot_clearance, axis=1)

        margin = 2 * self.robot_radius + self.discomfort_dist
        advice = (f"the pillars do not fit: {p} of obstacle_size = {self.obstacle_size:g} m, kept 2 · "
                  f"robot_radius + discomfort_dist = {margin:g} m apart, in the disc of radius obstacle_area "
                  f"· circle_radius = {reach:g} m (reduce n_obstacles or obstacle_size, or enlarge "
                  "obstacle_area or circle_radius)")
        for q in range(p):
            centres[:, q] = rejection_sample(
                rng, draw, stream=STREAM_OBSTACLES, j=1 + q, radius=np.full(b, circum),
                ref_pos=centres[:, :q], ref_radius=np.full((b, q), circum), margin=margin,
                max_attempts=self.max_attempts, what=f"{self.name}: pillar {q}", accept=clear_of_robot,
                clear_of="the other pillars and the robot's start and goal", advice=advice)
        half = self.obstacle_size / 2
        corners = np.array([[-half, -half], [half, -half], [half, half], [-half, half]])
        c, s = np.cos(angles), np.sin(angles)
        rot = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)  # (B, P, 2, 2)
        squares = centres[:, :, None, :] + np.einsum("bpij,kj->bpki", rot, corners)
        return tuple(StaticMap(tuple(squares[i])) for i in range(b))

    def flows(self) -> list[Flow]:
        """Not used: the humans are placed on the circle by :meth:`sample_humans`."""
        raise NotImplementedError  # humans are placed on the circle below

    def sample_humans(self, rng: EpisodeRandom, indices: np.ndarray) -> HumanArrays:
        """CrowdSim's circle crossing, each start and its antipode also clear of the pillars."""
        b, n, r_circle = len(rng), self.n_humans, self.circle_radius
        maps = self._maps(rng, indices)
        start, radius, v_pref = np.zeros((b, n, 2)), np.zeros((b, n)), np.zeros((b, n))
        ref_pos = np.zeros((b, 2 + 2 * n, 2))
        ref_pos[:, 0], ref_pos[:, 1] = (0.0, -r_circle), (0.0, r_circle)
        ref_rad = np.zeros((b, 2 + 2 * n))
        ref_rad[:, :2] = self.robot_radius
        for j in range(n):
            radius[:, j], v_pref[:, j] = self.human_attributes(rng, j)
            clear = self._clear_of_walls(maps, radius[:, j])

            def draw(sub: EpisodeRandom, key: tuple[int, ...], rows: np.ndarray) -> np.ndarray:
                u = sub.random(key, 3)
                angle = u[:, 0] * (2.0 * np.pi)
                noise = (2.0 * u[:, 1:] - 1.0) * 0.5
                return r_circle * np.stack([np.cos(angle), np.sin(angle)], axis=1) + noise

            m = 2 + 2 * j
            start[:, j] = rejection_sample(
                rng, draw, stream=STREAM_START, j=j, radius=radius[:, j], ref_pos=ref_pos[:, :m],
                ref_radius=ref_rad[:, :m], margin=self.discomfort_dist, max_attempts=self.max_attempts,
                what=f"{self.name}: start of human {j}",
                accept=lambda rows, p, c=clear: c(rows, p) & c(rows, -p))
            ref_pos[:, m], ref_pos[:, m + 1] = start[:, j], -start[:, j]
            ref_rad[:, m : m + 2] = radius[:, j, None]
        return HumanArrays(start=start, goal=-start, radius=radius, v_pref=v_pref)
