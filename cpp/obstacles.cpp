#include "obstacles.hpp"

#include <algorithm>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>

namespace socialnav {

void build_obstacle_vertices(const double* vertices, const int64_t* offsets, int n_polygons, ObstacleVertex* out) {
  for (int p = 0; p < n_polygons; ++p) {
    const int64_t first = offsets[p];
    const int k = static_cast<int>(offsets[p + 1] - first);
    if (k < 2)
      throw std::invalid_argument("obstacle polygon " + std::to_string(p) + " has " + std::to_string(k) +
                                  " vertices; at least 2 are needed");
    for (int i = 0; i < k; ++i) {
      const int64_t v = first + i;
      ObstacleVertex& o = out[v];
      o.point = Vec2{vertices[2 * v], vertices[2 * v + 1]};
      if (!std::isfinite(o.point.x) || !std::isfinite(o.point.y))
        throw std::invalid_argument("obstacle polygon " + std::to_string(p) + ": vertex " + std::to_string(i) +
                                    " is not finite");
      o.next = static_cast<int32_t>(first + (i + 1) % k);
      o.prev = static_cast<int32_t>(first + (i + k - 1) % k);
      o.solid = k >= 3;
      o.own_edge = k >= 3 || i == 0;
    }
    for (int i = 0; i < k; ++i) {
      ObstacleVertex& o = out[first + i];
      const Vec2 edge = out[o.next].point - o.point;
      if (!(abs_sq(edge) > 0.0))
        throw std::invalid_argument("obstacle polygon " + std::to_string(p) + ": vertices " + std::to_string(i) +
                                    " and " + std::to_string((i + 1) % k) + " coincide");
      o.unit_dir = normalize(edge);
      o.edge = edge;
      o.inv_edge_len_sq = 1.0 / abs_sq(edge);
      // RVO2: a vertex is convex when the polygon turns left (or goes straight) there; both ends of
      // a wall segment are convex.
      o.convex = k == 2 || left_of(out[o.prev].point, o.point, out[o.next].point) >= 0.0;
    }
  }
}

void build_edge_arrays(const ObstacleVertex* vertex, int count, double* edges) {
  for (int i = 0; i < count; ++i) {
    edges[i] = vertex[i].point.x;
    edges[count + i] = vertex[i].point.y;
    edges[2 * count + i] = vertex[i].edge.x;
    edges[3 * count + i] = vertex[i].edge.y;
    edges[4 * count + i] = vertex[i].inv_edge_len_sq;
  }
}

PreparedObstacles prepare_obstacles(const double* vertices, const int64_t* offsets, int n_polygons) {
  PreparedObstacles out;
  const int64_t count = n_polygons > 0 ? offsets[n_polygons] : 0;
  out.vertex.resize(static_cast<size_t>(count));
  out.edges.resize(static_cast<size_t>(5 * count));
  build_obstacle_vertices(vertices, offsets, n_polygons, out.vertex.data());
  build_edge_arrays(out.vertex.data(), static_cast<int>(count), out.edges.data());
  return out;
}

namespace {

// True when polygons [p0, p0 + n) and [q0, q0 + n) have the same vertex counts and coordinates (bit
// for bit: -0.0 and 0.0 differ, so a shared copy gives exactly the values its own would).
bool same_polygons(const double* vertices, const int64_t* o, int64_t p0, int64_t q0, int64_t n) {
  for (int64_t p = 0; p < n; ++p)
    if (o[p0 + p + 1] - o[p0 + p] != o[q0 + p + 1] - o[q0 + p]) return false;
  const int64_t v = o[p0 + n] - o[p0];
  return std::memcmp(vertices + 2 * o[p0], vertices + 2 * o[q0], static_cast<size_t>(2 * v) * sizeof(double)) == 0;
}

}  // namespace

PreparedObstacleBatch prepare_obstacle_batch(const double* vertices, const int64_t* o, int n_polygons,
                                             const int64_t* ep, int64_t batch) {
  const size_t B = static_cast<size_t>(batch);
  if (ep[0] != 0 || ep[B] != n_polygons) throw std::invalid_argument("episode_polygons must run from 0 to P");
  for (size_t b = 0; b < B; ++b)
    if (ep[b + 1] < ep[b]) throw std::invalid_argument("episode_polygons must not decrease");
  PreparedObstacleBatch out;
  out.first.resize(B);
  out.count.resize(B);
  std::vector<int64_t> rebased;
  std::vector<size_t> own;  // the episodes with a copy of their own
  int64_t prepared = 0;
  for (size_t b = 0; b < B; ++b) {
    const int64_t n = ep[b + 1] - ep[b];
    if (b > 0 && n == ep[b] - ep[b - 1] && same_polygons(vertices, o, ep[b], ep[b - 1], n)) {
      out.first[b] = out.first[b - 1];
      out.count[b] = out.count[b - 1];
      continue;
    }
    const int64_t v0 = o[ep[b]];
    const int64_t count = o[ep[b + 1]] - v0;
    rebased.resize(static_cast<size_t>(n) + 1);
    for (int64_t p = 0; p <= n; ++p) rebased[p] = o[ep[b] + p] - v0;
    out.vertex.resize(static_cast<size_t>(prepared + count));
    build_obstacle_vertices(vertices + 2 * v0, rebased.data(), static_cast<int>(n), out.vertex.data() + prepared);
    out.first[b] = prepared;
    out.count[b] = static_cast<int32_t>(count);
    own.push_back(b);
    prepared += count;
  }
  out.edges.resize(static_cast<size_t>(5 * prepared));
  for (size_t b : own)
    build_edge_arrays(out.vertex.data() + out.first[b], out.count[b], out.edges.data() + 5 * out.first[b]);
  return out;
}

double segment_segment_distance(Vec2 p0, Vec2 p1, Vec2 a, Vec2 b) {
  const Vec2 d = p1 - p0;
  if (abs_sq(d) > 0.0) {
    // Proper crossing: a and b on strictly opposite sides of p0p1 and p0, p1 of ab.
    const double s1 = det(d, a - p0), s2 = det(d, b - p0);
    const double s3 = det(b - a, p0 - a), s4 = det(b - a, p1 - a);
    if (((s1 > 0.0 && s2 < 0.0) || (s1 < 0.0 && s2 > 0.0)) && ((s3 > 0.0 && s4 < 0.0) || (s3 < 0.0 && s4 > 0.0)))
      return 0.0;
  }
  double best = dist_sq_point_segment(a, b, p0);
  if (abs_sq(d) > 0.0) {
    best = std::min(best, dist_sq_point_segment(a, b, p1));
    best = std::min(best, dist_sq_point_segment(p0, p1, a));
    best = std::min(best, dist_sq_point_segment(p0, p1, b));
  }
  return std::sqrt(best);
}

bool inside_solid(const ObstacleView& obstacles, Vec2 c) {
  bool parity = false;
  for (int i = 0; i < obstacles.count; ++i) {
    const ObstacleVertex& v = obstacles.vertex[i];
    if (!v.solid) continue;
    const Vec2 a = v.point, b = obstacles.vertex[v.next].point;
    if ((a.y > c.y) != (b.y > c.y) && c.x < a.x + (c.y - a.y) * (b.x - a.x) / (b.y - a.y)) parity = !parity;
    if (v.next < i) {  // the polygon's last vertex: decide for this polygon
      if (parity) return true;
      parity = false;
    }
  }
  return false;
}

bool disc_touches_obstacles(const ObstacleView& obstacles, Vec2 c, double radius) {
  const int n = obstacles.count;
  const double* __restrict px = obstacles.edges;
  const double* __restrict py = px + n;
  const double* __restrict ex = px + 2 * n;
  const double* __restrict ey = px + 3 * n;
  const double* __restrict inv = px + 4 * n;
  // Branch-free over every edge (a wall's return face gives the same distance as its own): the
  // compiler vectorises it, where the per-edge culling of swept_disc_hits_obstacles branches.
  double best = std::numeric_limits<double>::infinity();
  for (int i = 0; i < n; ++i) {
    const double tx = c.x - px[i], ty = c.y - py[i];
    const double r = std::min(std::max((tx * ex[i] + ty * ey[i]) * inv[i], 0.0), 1.0);
    const double dx = tx - r * ex[i], dy = ty - r * ey[i];
    best = std::min(best, dx * dx + dy * dy);
  }
  return best < radius * radius || inside_solid(obstacles, c);  // inside_solid skips wall segments
}

double swept_obstacle_clearance(const ObstacleView& obstacles, Vec2 p0, Vec2 p1, double radius) {
  double best = std::numeric_limits<double>::infinity();
  bool any_solid = false;
  for (int i = 0; i < obstacles.count; ++i) {
    const ObstacleVertex& v = obstacles.vertex[i];
    any_solid = any_solid || v.solid;
    if (!v.own_edge) continue;
    best = std::min(best, segment_segment_distance(p0, p1, v.point, obstacles.vertex[v.next].point));
  }
  if (any_solid && best > 0.0 && inside_solid(obstacles, p1)) best = 0.0;
  return best - radius;
}

bool swept_disc_hits_obstacles(const ObstacleView& obstacles, Vec2 p0, Vec2 p1, double radius) {
  // Culling margin [m]: far above the rounding error of a distance between map-sized coordinates, so
  // a culled edge's computed distance could never have been below the radius.
  constexpr double kCullMargin = 1e-6;
  const double path_min_x = std::min(p0.x, p1.x), path_max_x = std::max(p0.x, p1.x);
  const double path_min_y = std::min(p0.y, p1.y), path_max_y = std::max(p0.y, p1.y);
  const double reach = radius + kCullMargin;
  bool any_solid = false;
  for (int i = 0; i < obstacles.count; ++i) {
    const ObstacleVertex& v = obstacles.vertex[i];
    any_solid = any_solid || v.solid;
    if (!v.own_edge) continue;
    const Vec2 a = v.point, b = obstacles.vertex[v.next].point;
    if (std::min(a.x, b.x) - path_max_x > reach || path_min_x - std::max(a.x, b.x) > reach ||
        std::min(a.y, b.y) - path_max_y > reach || path_min_y - std::max(a.y, b.y) > reach)
      continue;
    // min over edges, minus the radius, is below 0 as soon as one edge's distance minus it is.
    if (segment_segment_distance(p0, p1, a, b) - radius < 0.0) return true;
  }
  // Every distance d has d - radius >= 0, so d >= radius: the clearance can only be below 0 through
  // the end point inside a solid polygon (clearance -radius), where radius > 0 (then every d > 0).
  return any_solid && radius > 0.0 && inside_solid(obstacles, p1);
}

}  // namespace socialnav
