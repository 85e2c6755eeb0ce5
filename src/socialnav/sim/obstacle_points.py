"""Obstacles as points for the networks: the nearest points of the obstacles' outlines.

A value network of the CrowdNav family reads a set of agents (position, velocity, radius). A wall
or a solid polygon is given to it the same way: its outline is sampled at a fixed spacing, and the
``count`` sampled points nearest to the robot within ``range`` become standing agents of radius
``radius`` (zero velocity), appended after the human slots with their own mask. The attention,
graph and LSTM networks then need no new layer, and an open floor adds nothing. The choice of the
numbers and why: docs/walls_learned.md.

Sampling (:func:`outline_points`): every edge is cut into ``ceil(length / spacing)`` equal parts and
a point put at each cut, so the spacing along an edge is at most ``spacing`` and every vertex is a
point (corners and door jambs are exact). A wall segment (2 vertices) gives both of its ends; a
polygon gives each vertex once. Points are selected by the distance of their centre to the robot's
centre; ties keep the outline's order (polygon after polygon, edge after edge).

NumPy only: the simulator, the Gymnasium learner observations and the value policies share it.
"""

from __future__ import annotations

import dataclasses
import math
import weakref
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from socialnav.maps.static_map import StaticMap
from socialnav.settings import check

__all__ = ["ObstaclePoints", "outline_points", "append_obstacle_agents"]


@dataclass(frozen=True)
class ObstaclePoints:
    """The encoding of the obstacles near the robot as ``count`` points (recorded in checkpoints).

    Attributes:
        count: K, the number of point slots (the nearest K points are kept, the rest padded).
        spacing: s [m], the largest distance between neighbouring points along an edge.
        range: r [m], points whose centre is farther than this from the robot's centre are left out.
        radius: ρ [m], the radius the points are given as agents (see docs/walls_learned.md).
    """

    count: int = 16
    spacing: float = 0.5
    range: float = 4.0
    radius: float = 0.1

    def __post_init__(self) -> None:
        check(isinstance(self.count, int) and not isinstance(self.count, bool) and self.count >= 1,
              "obstacle_encoding.count", self.count, "must be an integer >= 1")
        for name in ("spacing", "range"):
            value = getattr(self, name)
            check(isinstance(value, int | float) and math.isfinite(value) and value > 0,
                  f"obstacle_encoding.{name}", value, "must be a finite number > 0")
        check(isinstance(self.radius, int | float) and math.isfinite(self.radius) and self.radius >= 0,
              "obstacle_encoding.radius", self.radius, "must be a finite number >= 0")

    def to_dict(self) -> dict[str, Any]:
        """The encoding as a dict with ``kind`` (stored in checkpoints)."""
        return {"kind": "outline_points", **dataclasses.asdict(self)}

    @classmethod
    def from_dict(cls, data: Any) -> ObstaclePoints:
        """The encoding a checkpoint or a settings file records (``kind`` must be ``outline_points``)."""
        from socialnav.settings import from_dict

        if isinstance(data, ObstaclePoints):
            return data
        check(isinstance(data, dict), "obstacle_encoding", data, "must be a mapping")
        data = dict(data)
        kind = data.pop("kind", "outline_points")
        check(kind == "outline_points", "obstacle_encoding.kind", kind, "must be 'outline_points'")
        return from_dict(cls, data, "obstacle_encoding")

    def nearest(
        self, positions: np.ndarray, maps: Sequence[StaticMap | None]
    ) -> tuple[np.ndarray, np.ndarray]:
        """The kept points of B episodes and their mask.

        (B, K, 2) world-frame positions [m] (nearest first, zero rows where padded) and the mask (B, K) bool.

        Args:
            positions: (B, 2) the robots' positions [m].
            maps: (B,) each episode's map, None for an open floor.
        """
        positions = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
        b, k = positions.shape[0], self.count
        if len(maps) != b:
            raise ValueError(f"{len(maps)} maps for {b} robot positions")
        points = np.zeros((b, k, 2))
        mask = np.zeros((b, k), dtype=bool)
        groups: dict[int, list[int]] = {}
        for row, static_map in enumerate(maps):
            if static_map:
                groups.setdefault(id(static_map), []).append(row)
        for rows_list in groups.values():  # episodes of one scenario share their map object
            rows = np.asarray(rows_list)
            outline = outline_points(maps[rows_list[0]], self.spacing)  # (P, 2)
            d = np.hypot(outline[None, :, 0] - positions[rows, None, 0],
                         outline[None, :, 1] - positions[rows, None, 1])  # (G, P)
            d = np.where(d <= self.range, d, np.inf)
            order = np.argsort(d, axis=1, kind="stable")[:, :k]  # nearest first, ties in outline order
            kept = np.take_along_axis(d, order, axis=1) < np.inf
            n = order.shape[1]
            points[rows, :n] = np.where(kept[..., None], outline[order], 0.0)
            mask[rows, :n] = kept
        return points, mask

    def agents(
        self, positions: np.ndarray, maps: Sequence[StaticMap | None]
    ) -> tuple[np.ndarray, np.ndarray]:
        """The kept points as standing agents, and their mask.

        (B, K, 5) rows px, py, 0, 0, radius [m] (zero rows where padded) and the mask (B, K) bool.
        """
        points, mask = self.nearest(positions, maps)
        out = np.zeros((*mask.shape, 5))
        out[..., :2] = points
        out[..., 4] = np.where(mask, self.radius, 0.0)
        return out, mask


_OUTLINES: dict[tuple[int, float], tuple[weakref.ref, np.ndarray]] = {}


def outline_points(static_map: StaticMap, spacing: float) -> np.ndarray:
    """Points along every obstacle outline of ``static_map``: (P, 2) [m].

    At most ``spacing`` apart along an edge, every vertex included, polygon after polygon (read-only, cached
    per map).
    """
    key = (id(static_map), float(spacing))
    hit = _OUTLINES.get(key)
    if hit is not None and hit[0]() is static_map:
        return hit[1]
    parts = []
    for poly in static_map.polygons:
        closed = len(poly) >= 3
        ends = np.roll(poly, -1, axis=0) if closed else poly[1:]
        for a, b in zip(poly[: len(ends)], ends, strict=True):
            n = max(1, math.ceil(float(np.hypot(*(b - a))) / spacing - 1e-9))
            t = np.arange(n) / n  # the edge's end is the next edge's start (or added below)
            parts.append(a + t[:, None] * (b - a))
        if not closed:
            parts.append(poly[-1:])
    out = np.concatenate(parts) if parts else np.zeros((0, 2))
    out.setflags(write=False)
    if len(_OUTLINES) > 4096:  # maps drawn per episode: forget the old ones
        _OUTLINES.clear()
    _OUTLINES[key] = (weakref.ref(static_map), out)
    return out


def append_obstacle_agents(
    robot: np.ndarray,
    humans: np.ndarray,
    mask: np.ndarray,
    maps: Sequence[StaticMap | None] | None,
    encoding: ObstaclePoints,
) -> tuple[np.ndarray, np.ndarray]:
    """``humans`` and ``mask`` with the encoding's K point slots appended after the human slots.

    ``humans`` (B, N, 5) and ``mask`` (B, N) become (B, N + K, 5) and (B, N + K). ``maps`` None: every episode
    is an open floor.
    """
    robot = np.asarray(robot, dtype=np.float64)
    maps = [None] * robot.shape[0] if maps is None else maps
    points, point_mask = encoding.agents(robot[:, :2], maps)
    humans = np.concatenate([np.asarray(humans, dtype=np.float64), points], axis=1)
    return humans, np.concatenate([np.asarray(mask, dtype=bool), point_mask], axis=1)
