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
  out.orca = build_orca_obstacles(out.vertex.data(), static_cast<int>(count));
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

// RVO2's tolerance (RVO_EPSILON) for an end point lying on a node's line.
constexpr double kTreeEpsilon = 1e-5;

// Builds RVO2's obstacle kd-tree over `ids` (vertices whose edges reach their `next`), splitting in
// `out.vertex` every edge that crosses the chosen node's line; returns the node's vertex (-1: none).
// Node choice: the edge whose line leaves the fewest edges on its larger side, then on its smaller side,
// the first such edge in list order; each side keeps list order, a split edge's two halves going to the
// sides their ends lie on.
int32_t build_tree(std::vector<int32_t>& ids, OrcaObstacles& out, int32_t parent, bool is_left, int32_t depth) {
  const int n = static_cast<int>(ids.size());
  if (n == 0) return -1;
  auto side_counts = [&](int i, int limit_big, int limit_small, int& left, int& right) {
    const ObstacleVertex& i1 = out.vertex[ids[i]];
    const Vec2 a = i1.point, b = out.vertex[i1.next].point;
    left = right = 0;
    for (int j = 0; j < n; ++j) {
      if (j == i) continue;
      const ObstacleVertex& j1 = out.vertex[ids[j]];
      const double l1 = left_of(a, b, j1.point), l2 = left_of(a, b, out.vertex[j1.next].point);
      if (l1 >= -kTreeEpsilon && l2 >= -kTreeEpsilon) {
        ++left;
      } else if (l1 <= kTreeEpsilon && l2 <= kTreeEpsilon) {
        ++right;
      } else {
        ++left;
        ++right;
      }
      const int big = std::max(left, right), small = std::min(left, right);
      if (big > limit_big || (big == limit_big && small >= limit_small)) return false;  // no better
    }
    return true;
  };
  int best = 0, best_big = n, best_small = n;
  for (int i = 0; i < n; ++i) {
    int left = 0, right = 0;
    if (side_counts(i, best_big, best_small, left, right)) {
      const int big = std::max(left, right), small = std::min(left, right);
      if (big < best_big || (big == best_big && small < best_small)) {
        best = i;
        best_big = big;
        best_small = small;
      }
    }
  }
  const int32_t node = ids[best];
  const Vec2 a = out.vertex[node].point, b = out.vertex[out.vertex[node].next].point;
  std::vector<int32_t> left_ids, right_ids;
  for (int j = 0; j < n; ++j) {
    if (j == best) continue;
    const int32_t j1 = ids[j];
    const int32_t j2 = out.vertex[j1].next;
    const double l1 = left_of(a, b, out.vertex[j1].point), l2 = left_of(a, b, out.vertex[j2].point);
    if (l1 >= -kTreeEpsilon && l2 >= -kTreeEpsilon) {
      left_ids.push_back(j1);
    } else if (l1 <= kTreeEpsilon && l2 <= kTreeEpsilon) {
      right_ids.push_back(j1);
    } else {
      // The edge j1 -> j2 crosses the node's line: a new convex vertex where it does, taking the
      // direction of the edge it cuts (as RVO2 does, not recomputed).
      const Vec2 p1 = out.vertex[j1].point, p2 = out.vertex[j2].point;
      const double t = det(b - a, p1 - a) / det(b - a, p1 - p2);
      ObstacleVertex split = out.vertex[j1];
      split.point = p1 + t * (p2 - p1);
      split.prev = j1;
      split.next = j2;
      split.convex = true;
      const int32_t k = static_cast<int32_t>(out.vertex.size());
      out.vertex.push_back(split);
      out.vertex[j1].next = k;
      out.vertex[j2].prev = k;
      if (l1 > 0.0) {
        left_ids.push_back(j1);
        right_ids.push_back(k);
      } else {
        right_ids.push_back(j1);
        left_ids.push_back(k);
      }
    }
  }
  out.parent.resize(out.vertex.size(), -1);
  out.is_left.resize(out.vertex.size(), 0);
  out.depth.resize(out.vertex.size(), 0);
  out.parent[node] = parent;
  out.is_left[node] = is_left ? 1 : 0;
  out.depth[node] = depth;
  ids.clear();  // the caller's list is not needed below: release it before recursing
  ids.shrink_to_fit();
  build_tree(left_ids, out, node, true, depth + 1);
  build_tree(right_ids, out, node, false, depth + 1);
  return node;
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
  // RVO2's split map and tree of each distinct map, shared by the episodes that share its vertices.
  out.orca_first.resize(B);
  out.orca_count.resize(B);
  for (size_t b = 0; b < B; ++b) {
    if (b > 0 && out.first[b] == out.first[b - 1] && out.count[b] == out.count[b - 1] && out.count[b] > 0) {
      out.orca_first[b] = out.orca_first[b - 1];
      out.orca_count[b] = out.orca_count[b - 1];
      continue;
    }
    const OrcaObstacles one = build_orca_obstacles(out.vertex.data() + out.first[b], out.count[b]);
    out.orca_first[b] = static_cast<int64_t>(out.orca.vertex.size());
    out.orca_count[b] = static_cast<int32_t>(one.vertex.size());
    out.orca.vertex.insert(out.orca.vertex.end(), one.vertex.begin(), one.vertex.end());
    out.orca.edges.insert(out.orca.edges.end(), one.edges.begin(), one.edges.end());  // its own 7 arrays
    out.orca.parent.insert(out.orca.parent.end(), one.parent.begin(), one.parent.end());
    out.orca.is_left.insert(out.orca.is_left.end(), one.is_left.begin(), one.is_left.end());
    out.orca.depth.insert(out.orca.depth.end(), one.depth.begin(), one.depth.end());
  }
  return out;
}

OrcaObstacles build_orca_obstacles(const ObstacleVertex* vertex, int count) {
  OrcaObstacles out;
  out.vertex.assign(vertex, vertex + count);
  std::vector<int32_t> ids(static_cast<size_t>(count));
  for (int i = 0; i < count; ++i) ids[i] = i;
  build_tree(ids, out, -1, false, 0);
  // Edge vectors of the vertices a split changed (the cut edges' first halves and the split points).
  for (ObstacleVertex& v : out.vertex) {
    v.edge = out.vertex[v.next].point - v.point;
    v.inv_edge_len_sq = 1.0 / abs_sq(v.edge);
  }
  out.edges.resize(7 * out.vertex.size());
  build_orca_edge_arrays(out.vertex.data(), static_cast<int>(out.vertex.size()), out.edges.data());
  return out;
}

void build_orca_edge_arrays(const ObstacleVertex* vertex, int count, double* edges) {
  for (int i = 0; i < count; ++i) {
    const ObstacleVertex& v = vertex[i];
    const Vec2 next = vertex[v.next].point;
    edges[i] = v.point.x;
    edges[count + i] = v.point.y;
    edges[2 * count + i] = v.edge.x;
    edges[3 * count + i] = v.edge.y;
    edges[4 * count + i] = abs_sq(v.edge);
    edges[5 * count + i] = next.x;
    edges[6 * count + i] = next.y;
  }
}

bool tree_query_precedes(const ObstacleView& view, int a, int b, Vec2 position) {
  // The query visits a node's near subtree (the side of its line the agent is on, left when on the
  // line), then the node, then the far subtree. Climb to the children of the two nodes' meeting point.
  int ua = a, ub = b;
  bool a_left = false, b_left = false;  // side of the last step up from a and from b
  while (view.tree_depth[ua] > view.tree_depth[ub]) {
    a_left = view.tree_is_left[ua] != 0;
    ua = view.tree_parent[ua];
  }
  while (view.tree_depth[ub] > view.tree_depth[ua]) {
    b_left = view.tree_is_left[ub] != 0;
    ub = view.tree_parent[ub];
  }
  auto near_is_left = [&](int node) {
    const ObstacleVertex& v = view.vertex[node];
    return left_of(v.point, view.vertex[v.next].point, position) >= 0.0;
  };
  if (ua == ub) {                                   // one node is the other's ancestor
    if (ua == a) return b_left != near_is_left(a);  // a first unless b lies in a's near subtree
    return a_left == near_is_left(b);
  }
  while (view.tree_parent[ua] != view.tree_parent[ub]) {
    ua = view.tree_parent[ua];
    ub = view.tree_parent[ub];
  }
  return (view.tree_is_left[ua] != 0) == near_is_left(view.tree_parent[ua]);
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

bool inside_solid(const ObstacleView& obstacles, Vec2 c) { return inside_solid(obstacles, c, 0, obstacles.count); }

bool inside_solid(const ObstacleView& obstacles, Vec2 c, int begin, int end) {
  bool parity = false;
  for (int i = begin; i < end; ++i) {
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
  return swept_obstacle_clearance(obstacles, p0, p1, radius, 0, obstacles.count);
}

double swept_obstacle_clearance(const ObstacleView& obstacles, Vec2 p0, Vec2 p1, double radius, int begin, int end) {
  double best = std::numeric_limits<double>::infinity();
  bool any_solid = false;
  for (int i = begin; i < end; ++i) {
    const ObstacleVertex& v = obstacles.vertex[i];
    any_solid = any_solid || v.solid;
    if (!v.own_edge) continue;
    best = std::min(best, segment_segment_distance(p0, p1, v.point, obstacles.vertex[v.next].point));
  }
  if (any_solid && best > 0.0 && inside_solid(obstacles, p1, begin, end)) best = 0.0;
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
