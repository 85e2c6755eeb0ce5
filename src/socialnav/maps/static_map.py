"""The static map of an episode: walls and other obstacles as polygons.

A :class:`StaticMap` is the one representation of obstacles that scenarios generate, the world
simulates, trajectories carry and metrics score. It depends on NumPy only, so it sits below every
other package (scenarios, sim, trajectory, metrics, viz).

Geometry conventions (see ``docs/walls_maps.md``):

- a polygon is a vertex list of shape (k, 2) in metres, k >= 2;
- k == 2 is a wall segment (two-sided, zero thickness);
- k >= 3 is a closed, simple (not self-intersecting) polygon; its interior is solid. Vertices are
  stored counter-clockwise: clockwise input is reversed on construction, since RVO2's obstacle
  algorithm relies on the orientation to tell convex from non-convex vertices;
- an empty map (no polygons) is the open floor of the original protocol;
- every coordinate is finite and at most :data:`MAX_COORDINATE` (1e6 m, 1000 km) in magnitude, so
  that squared distances and cross products between vertices stay finite and precise in float64.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["MAX_COORDINATE", "MapError", "MapStack", "StaticMap"]

#: The largest magnitude [m] of a map coordinate. A map wider than 1000 km means nothing to a pedestrian
#: simulator; a bound this size keeps every squared distance and cross product the geometry forms
#: (at most ~1e13 m^2) finite, with float64 rounding errors far below a micrometre; coordinates near
#: 1e308 would overflow to inf/NaN and make every distance to the walls NaN.
MAX_COORDINATE = 1e6


class MapError(ValueError):
    """A map or polygon is invalid; the message names the polygon (0-based index) and the vertex."""


def _segments_cross(p1: np.ndarray, p2: np.ndarray, q1: np.ndarray, q2: np.ndarray) -> bool:
    """True when closed segments p1p2 and q1q2 share a point (touching counts)."""

    def orient(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> float:
        return float((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))

    def on_segment(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> bool:
        return bool(min(a[0], b[0]) <= c[0] <= max(a[0], b[0]) and min(a[1], b[1]) <= c[1] <= max(a[1], b[1]))

    d1, d2 = orient(q1, q2, p1), orient(q1, q2, p2)
    d3, d4 = orient(p1, p2, q1), orient(p1, p2, q2)
    if ((d1 > 0) != (d2 > 0)) and d1 != 0 and d2 != 0 and ((d3 > 0) != (d4 > 0)) and d3 != 0 and d4 != 0:
        return True
    return (
        (d1 == 0 and on_segment(q1, q2, p1))
        or (d2 == 0 and on_segment(q1, q2, p2))
        or (d3 == 0 and on_segment(p1, p2, q1))
        or (d4 == 0 and on_segment(p1, p2, q2))
    )


def _signed_area(v: np.ndarray) -> float:
    x, y = v[:, 0], v[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _check_polygon(v: np.ndarray, index: int) -> np.ndarray:
    """Validate one polygon and return it counter-clockwise, read-only."""
    if v.ndim != 2 or v.shape[1] != 2 or v.shape[0] < 2:
        raise MapError(f"polygon {index}: expected a (k, 2) vertex list with k >= 2, got shape {v.shape}")
    if not np.isfinite(v).all():
        bad = int(np.argwhere(~np.isfinite(v))[0][0])
        raise MapError(f"polygon {index}: vertex {bad} is not finite: {v[bad].tolist()}")
    if np.abs(v).max() > MAX_COORDINATE:
        bad, axis = (int(i) for i in np.argwhere(np.abs(v) > MAX_COORDINATE)[0])
        raise MapError(f"polygon {index}: vertex {bad} is out of range: {'xy'[axis]} = {v[bad, axis]:g} (map "
                       f"coordinates are limited to |x|, |y| <= {MAX_COORDINATE:,.0f} m): {v[bad].tolist()}")
    k = v.shape[0]
    edges = np.linalg.norm(np.roll(v, -1, axis=0) - v, axis=1)
    n_edges = 1 if k == 2 else k
    for e in range(n_edges):
        if edges[e] <= 1e-9:
            raise MapError(f"polygon {index}: vertices {e} and {(e + 1) % k} coincide ({v[e].tolist()})")
    if k >= 3:
        for a in range(k):
            for b in range(a + 2, k):
                if a == 0 and b == k - 1:
                    continue  # adjacent through the closing edge
                if _segments_cross(v[a], v[(a + 1) % k], v[b], v[(b + 1) % k]):
                    raise MapError(
                        f"polygon {index}: self-intersecting (edge {a}-{(a + 1) % k} crosses "
                        f"edge {b}-{(b + 1) % k})"
                    )
        area = _signed_area(v)
        if abs(area) <= 1e-12:
            raise MapError(f"polygon {index}: zero area (all vertices on one line)")
        if area < 0.0:
            v = v[::-1].copy()
    v = np.ascontiguousarray(v, dtype=np.float64)
    v.setflags(write=False)
    return v


@dataclass(frozen=True, eq=False)
class StaticMap:
    """Obstacles fixed for one episode.

    Attributes:
        polygons: Vertex lists [m], each of shape (k, 2); k == 2 is a wall segment, k >= 3 a solid
            simple polygon stored counter-clockwise. Read-only float64 arrays.
    """

    polygons: tuple[np.ndarray, ...] = ()

    def __post_init__(self) -> None:
        if isinstance(self.polygons, str | bytes) or hasattr(self.polygons, "__fspath__"):
            raise MapError(f"StaticMap takes polygons, not a file ({self.polygons!r}): read a map file with "
                           "socialnav.maps.load_map")
        if isinstance(self.polygons, dict):
            keys = sorted(map(str, self.polygons))
            raise MapError("StaticMap takes a sequence of polygons, not a dict: StaticMap.from_dict reads "
                           f"the dict form ({{'polygons': [...]}}), got keys {keys}")
        if not isinstance(self.polygons, Iterable):
            raise MapError(f"StaticMap takes a sequence of polygons (vertex lists), got "
                           f"{type(self.polygons).__name__} {self.polygons!r:.40}; an open floor is "
                           "StaticMap() or no map (None) where a map is optional")
        checked = []
        for i, poly in enumerate(self.polygons):
            try:
                arr = np.array(poly, dtype=np.float64)
            except (TypeError, ValueError) as exc:
                raise MapError(f"polygon {i}: cannot convert to a float array ({exc})") from exc
            checked.append(_check_polygon(arr, i))
        object.__setattr__(self, "polygons", tuple(checked))

    @classmethod
    def from_polygons(cls, polygons: Iterable[Any]) -> StaticMap:
        """Build a map from any iterable of (k, 2) vertex lists."""
        return cls(tuple(polygons))

    def __len__(self) -> int:
        return len(self.polygons)

    def __bool__(self) -> bool:
        return bool(self.polygons)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, StaticMap) or len(other.polygons) != len(self.polygons):
            return False
        pairs = zip(self.polygons, other.polygons, strict=True)
        return all(a.shape == b.shape and np.array_equal(a, b) for a, b in pairs)

    __hash__ = None  # type: ignore[assignment]

    @property
    def n_vertices(self) -> int:
        """The number of vertices over all polygons."""
        return sum(p.shape[0] for p in self.polygons)

    def to_flat(self) -> tuple[np.ndarray, np.ndarray]:
        """Structure-of-arrays form: vertices (V, 2) float64 and offsets (P + 1,) int64.

        Polygon p is ``vertices[offsets[p]:offsets[p + 1]]``; this is the layout the native world
        stores per episode.
        """
        counts = np.array([p.shape[0] for p in self.polygons], dtype=np.int64)
        offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        vertices = np.concatenate(self.polygons) if self.polygons else np.zeros((0, 2))
        return np.ascontiguousarray(vertices, dtype=np.float64), offsets

    @classmethod
    def from_flat(cls, vertices: np.ndarray, offsets: Sequence[int]) -> StaticMap:
        """Inverse of :meth:`to_flat`."""
        vertices = np.asarray(vertices, dtype=np.float64)
        offs = [int(o) for o in offsets]
        return cls(tuple(vertices[a:b] for a, b in zip(offs[:-1], offs[1:], strict=True)))

    def edges(self) -> tuple[np.ndarray, np.ndarray]:
        """All obstacle edges as start points (E, 2) and end points (E, 2)."""
        starts, ends = [], []
        for p in self.polygons:
            if p.shape[0] == 2:
                starts.append(p[:1])
                ends.append(p[1:])
            else:
                starts.append(p)
                ends.append(np.roll(p, -1, axis=0))
        if not starts:
            return np.zeros((0, 2)), np.zeros((0, 2))
        return np.concatenate(starts), np.concatenate(ends)

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Distance [m] from each point to the nearest obstacle; 0 inside a solid polygon.

        ``points`` has shape (..., 2); the result has shape (...). ``inf`` for an empty map.
        """
        pts = np.asarray(points, dtype=np.float64)
        flat = pts.reshape(-1, 2)
        if not self.polygons:
            return np.full(pts.shape[:-1], np.inf)
        a, b = self.edges()
        ab = b - a  # (E, 2)
        ap = flat[:, None, :] - a[None, :, :]  # (P, E, 2)
        denom = np.maximum(np.sum(ab * ab, axis=1), 1e-300)
        t = np.clip(np.sum(ap * ab[None], axis=2) / denom[None], 0.0, 1.0)
        closest = a[None] + t[..., None] * ab[None]
        dist = np.linalg.norm(flat[:, None, :] - closest, axis=2).min(axis=1)
        inside = self.contains(flat)
        dist[inside] = 0.0
        return dist.reshape(pts.shape[:-1])

    def contains(self, points: np.ndarray) -> np.ndarray:
        """True where a point lies inside a solid polygon (segments contain nothing)."""
        pts = np.asarray(points, dtype=np.float64)
        flat = pts.reshape(-1, 2)
        inside = np.zeros(flat.shape[0], dtype=bool)
        for p in self.polygons:
            if p.shape[0] < 3:
                continue
            x, y = flat[:, 0:1], flat[:, 1:2]
            x0, y0 = p[:, 0][None], p[:, 1][None]
            x1, y1 = np.roll(p[:, 0], -1)[None], np.roll(p[:, 1], -1)[None]
            crosses = (y0 > y) != (y1 > y)
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                x_at = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
            inside |= (np.sum(crosses & (x < x_at), axis=1) % 2 == 1)  # overlapping polygons: their union
        return inside.reshape(pts.shape[:-1])

    def to_dict(self) -> dict[str, Any]:
        """JSON/YAML-serialisable form: ``{"polygons": [[[x, y], ...], ...]}``."""
        return {"polygons": [p.tolist() for p in self.polygons]}

    @classmethod
    def from_dict(cls, data: Any) -> StaticMap:
        """Inverse of :meth:`to_dict`; a :class:`MapError` names what is wrong."""
        if not isinstance(data, dict):
            raise MapError(f"map: expected a mapping with a 'polygons' list, got {type(data).__name__}")
        unknown = sorted(str(k) for k in data if k != "polygons")
        if unknown or "polygons" not in data:
            found = f"unknown key(s) {', '.join(repr(k) for k in unknown)}" if unknown else "no keys"
            raise MapError(f"map: expected a mapping with one key, 'polygons' (a list of vertex lists); "
                           f"found {found}")
        polys = data["polygons"]
        if not isinstance(polys, list):
            raise MapError(f"map.polygons: expected a list, got {type(polys).__name__}")
        return cls(tuple(polys))


class MapStack:
    """One map per episode, stacked for vectorised queries: point i against map i.

    A batch of episodes with different maps (pillars drawn per episode) asks "how far is each
    episode's candidate from its own walls" once per placement attempt; the edges of all maps are
    padded into (B, E, 2) arrays once, so that each query is a few array operations instead of B
    calls of :meth:`StaticMap.distance`.
    """

    def __init__(self, maps: Sequence[StaticMap]):
        b = len(maps)
        per_map = [m.edges() for m in maps]
        n_edges = max((len(a) for a, _ in per_map), default=0)
        n_solid = max((sum(p.shape[0] >= 3 for p in m.polygons) for m in maps), default=0)
        self.starts = np.zeros((b, n_edges, 2))
        self.ends = np.zeros((b, n_edges, 2))
        self.valid = np.zeros((b, n_edges), dtype=bool)
        # which solid polygon an edge closes (for the even-odd inside test), one-hot; segments: none
        self.solid = np.zeros((b, n_edges, max(n_solid, 1)), dtype=bool)
        for i, (m, (a, e)) in enumerate(zip(maps, per_map, strict=True)):
            self.starts[i, : len(a)], self.ends[i, : len(a)], self.valid[i, : len(a)] = a, e, True
            at, q = 0, 0
            for poly in m.polygons:
                k = poly.shape[0]
                if k == 2:
                    at += 1
                    continue
                self.solid[i, at : at + k, q] = True
                at, q = at + k, q + 1

    def __len__(self) -> int:
        return self.starts.shape[0]

    def take(self, rows: np.ndarray) -> MapStack:
        """The maps of ``rows`` (a view of the stacked arrays, no rebuilding)."""
        out = object.__new__(MapStack)
        out.starts, out.ends, out.valid, out.solid = (x[rows] for x in (self.starts, self.ends, self.valid,
                                                                         self.solid))
        return out

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Distance [m] from ``points[i, ...]`` to the obstacles of map i.

        0 inside a solid polygon, ``inf`` for an empty map. ``points`` has shape (B, ..., 2), the result
        (B, ...).
        """
        pts = np.asarray(points, dtype=np.float64)
        b = pts.shape[0]
        flat = pts.reshape(b, -1, 2)  # (B, M, 2)
        if self.starts.shape[1] == 0:
            return np.full(pts.shape[:-1], np.inf)
        a, ab = self.starts[:, None], (self.ends - self.starts)[:, None]  # (B, 1, E, 2)
        ap = flat[:, :, None, :] - a  # (B, M, E, 2)
        denom = np.maximum(np.sum(ab * ab, axis=-1), 1e-300)
        t = np.clip(np.sum(ap * ab, axis=-1) / denom, 0.0, 1.0)
        d = np.linalg.norm(ap - t[..., None] * ab, axis=-1)
        d = np.where(self.valid[:, None], d, np.inf).min(axis=-1)  # (B, M)
        # even-odd rule per solid polygon: a horizontal ray to -x crosses its edges an odd number of times
        x, y = flat[..., 0:1], flat[..., 1:2]  # (B, M, 1)
        x0, y0 = self.starts[:, None, :, 0], self.starts[:, None, :, 1]
        x1, y1 = self.ends[:, None, :, 0], self.ends[:, None, :, 1]
        straddles = (y0 > y) != (y1 > y)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            x_at = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
        crosses = (straddles & (x < x_at)).astype(np.int64)  # (B, M, E)
        counts = np.einsum("bme,bep->bmp", crosses, self.solid.astype(np.int64))
        inside = np.any(counts % 2 == 1, axis=-1)
        return np.where(inside, 0.0, d).reshape(pts.shape[:-1])
