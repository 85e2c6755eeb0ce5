#include "routes.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <deque>
#include <limits>
#include <mutex>
#include <queue>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>

#include "multiversion.hpp"

namespace socialnav {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// Nodes sit this factor farther than d from the edges' lines, so that the segment between two nodes of
// one edge passes the d test despite rounding.
constexpr double kNodeSlack = 1.01;
// A tested clearance never drops below this [m]: a segment through a wall has distance 0 and must fail.
constexpr double kMinClearance = 1e-6;

inline Vec2 right_normal(Vec2 u) { return Vec2{u.y, -u.x}; }

#define SOCIALNAV_INLINE __attribute__((always_inline))

// Vectors of kEdgeLanes doubles (GCC's vector extension: each operation is the scalar one, lane by lane).
// They never cross a call (the helpers below are always inlined), so the warning that passing them without
// AVX would change the ABI does not apply. The helpers are called from always-inlined functions without
// vector parameters, never straight from an AVX2 clone: Clang refuses such a call (the clone has AVX, the
// helper has not), inlined or not.
#pragma GCC diagnostic ignored "-Wpsabi"
typedef double Lanes __attribute__((vector_size(kEdgeLanes * sizeof(double))));

SOCIALNAV_INLINE inline Lanes load_lanes(const double* p) {
  Lanes v;
  std::memcpy(&v, p, sizeof(v));
  return v;
}
SOCIALNAV_INLINE inline Lanes lanes_of(double x) { return Lanes{} + x; }
// std::min(a, b) and std::max(a, b), lane by lane
SOCIALNAV_INLINE inline Lanes lane_min(Lanes a, Lanes b) { return b < a ? b : a; }
SOCIALNAV_INLINE inline Lanes lane_max(Lanes a, Lanes b) { return a < b ? b : a; }
SOCIALNAV_INLINE inline Lanes clamp01(Lanes t) { return lane_min(lane_max(t, lanes_of(0.0)), lanes_of(1.0)); }
SOCIALNAV_INLINE inline double lanes_min(Lanes best) {
  double m = best[0];
  for (int l = 1; l < kEdgeLanes; ++l) m = std::min(m, best[l]);
  return m;
}

// The points beside vertex i at distance >= d from both of its edges' lines, on the free side: the miter
// point of the two offset lines where the corner is not sharp, else one point past each edge's end (a
// wall's end gets two, one per face).
void corner_nodes(const ObstacleView& obs, int i, double d, std::vector<Vec2>& out) {
  const ObstacleVertex& v = obs.vertex[i];
  if (!v.convex) return;
  const Vec2 u_out = v.unit_dir;
  const Vec2 u_in = obs.vertex[v.prev].unit_dir;
  const Vec2 n_in = right_normal(u_in), n_out = right_normal(u_out);
  const double cosine = dot(n_in, n_out);
  if (cosine > 0.999) return;  // a straight run of a chain: nothing to walk around
  const double dd = kNodeSlack * d;
  if (cosine > -0.3) {
    out.push_back(v.point + (dd / (1.0 + cosine)) * (n_in + n_out));
  } else {
    out.push_back(v.point + dd * (n_in + u_in));
    out.push_back(v.point + dd * (n_out - u_out));
  }
}

// The search's scratch arrays, one set per thread (one thread-local lookup per search).
struct SearchScratch {
  std::vector<int> prev;          // a settled node's predecessor on its route (-1: the start)
  std::vector<double> to_goal;    // the nodes' straight distances to the goal
  std::vector<double> start_key;  // a node's entry straight from the start (+inf once tested and hidden)
  std::vector<double> start_g;    // its route length (the straight distance)
  std::vector<double> graph_key;  // a node's best entry through the graph so far (+inf: none; -inf: settled)
  std::vector<double> graph_g;
  std::vector<int> graph_pred;
  std::vector<double> key;        // min(start_key, graph_key) of an unsettled node, +inf once settled (padded)
  std::vector<double> block_min;  // the least key of each kKeyBlock nodes
};

// The keys are scanned in blocks: the block of least minimum first, then its nodes.
constexpr int kKeyBlock = 8;

SOCIALNAV_INLINE inline void refresh_block(const double* __restrict key, double* __restrict block_min, int i) {
  const double* k = key + (i / kKeyBlock) * kKeyBlock;
  double m = k[0];
  for (int j = 1; j < kKeyBlock; ++j) m = k[j] < m ? k[j] : m;
  block_min[i / kKeyBlock] = m;
}

// This thread's scratch arrays, looked up once per search: a thread_local used in place would have its
// address computed afresh (a call into the dynamic linker) after every call the search makes.
__attribute__((noinline)) SearchScratch& thread_scratch() {
  thread_local SearchScratch scratch;
  return scratch;
}

// The search's first pass over the nodes: their straight distances to the goal and from the start (norm's
// arithmetic, lane by lane: the same values), and the start's entries as the keys.
SOCIALNAV_AVX2_CLONE void node_keys(const double* __restrict x, const double* __restrict y, int n, Vec2 start,
                                    Vec2 goal, double* __restrict to_goal, double* __restrict start_g,
                                    double* __restrict start_key, double* __restrict key) {
  for (int i = 0; i < n; ++i) {
    const double gx = goal.x - x[i], gy = goal.y - y[i];
    const double sx = x[i] - start.x, sy = y[i] - start.y;
    to_goal[i] = std::sqrt(gx * gx + gy * gy);
    start_g[i] = std::sqrt(sx * sx + sy * sy);
    start_key[i] = key[i] = start_g[i] + to_goal[i];
  }
}

// A* (P. E. Hart, N. J. Nilsson, B. Raphael, "A Formal Basis for the Heuristic Determination of Minimum Cost
// Paths", IEEE Trans. SSC 4(2), 1968) from `start` to `goal` over graph g, the straight distance to the goal
// its estimate: writes into s.prev the route's nodes back from `last` and returns true, or returns false
// where the graph joins them nowhere. The start's and the goal's segments to the nodes are checked lazily,
// when a node comes next (the graph's own edges were checked when it was built): the search stops as soon
// as no route through the remaining nodes can be shorter, so most of them are never tested. Each node
// keeps two candidates, the segment straight from the start and its shortest way through the graph so
// far; the next node is the one of smallest key (route length + estimate), the lower index among equal
// keys, found by a scan (a map's graph has tens of nodes: cheaper than a heap's pushes and moves). Routes
// of exactly equal length to a node (through collinear corners, or mirror images on a symmetric map) are
// common, so which one a node keeps is a rule: the one found first, the start's segment before any
// through the graph (docs/routes.md; tests/sim/test_routes.py records routes on symmetric maps).
//
// A way through the graph whose key is no less than the best route found so far is not recorded: such a
// node is never taken next (the search ends first), and a later way shorter than it replaces the older
// candidate all the same, so the route is the one the full bookkeeping would find.
bool search_route(const RouteGraph& g, Vec2 start, Vec2 goal, double c_start, double c_goal, const EdgeSet& walls,
                  const ObstacleView& obs, SearchScratch& s, int& last) {
  const int n = static_cast<int>(g.node.size());
  const int blocks = (n + kKeyBlock - 1) / kKeyBlock;
  s.prev.resize(static_cast<size_t>(n));
  s.to_goal.resize(static_cast<size_t>(n));
  s.start_key.resize(static_cast<size_t>(n));
  s.start_g.resize(static_cast<size_t>(n));
  s.graph_key.assign(static_cast<size_t>(n), kInf);
  s.graph_g.resize(static_cast<size_t>(n));
  s.graph_pred.resize(static_cast<size_t>(n));
  s.key.assign(static_cast<size_t>(blocks) * kKeyBlock, kInf);
  s.block_min.resize(static_cast<size_t>(blocks));
  // (the arrays as plain pointers: the compiler need not reload them from the vectors after each store)
  int* __restrict prev = s.prev.data();
  double* __restrict to_goal = s.to_goal.data();
  double* __restrict start_key = s.start_key.data();
  double* __restrict start_g = s.start_g.data();
  double* __restrict graph_key = s.graph_key.data();
  double* __restrict graph_g = s.graph_g.data();
  int* __restrict graph_pred = s.graph_pred.data();
  double* __restrict key = s.key.data();
  double* __restrict block_min = s.block_min.data();
  const Vec2* __restrict node = g.node.data();
  const int32_t* __restrict first = g.first.data();
  const int32_t* __restrict neighbour = g.neighbour.data();
  const double* __restrict length = g.length.data();
  node_keys(g.node_x.data(), g.node_y.data(), n, start, goal, to_goal, start_g, start_key, key);
  for (int b = 0; b < blocks; ++b) refresh_block(key, block_min, b * kKeyBlock);
  double best = kInf;
  last = -1;
  for (;;) {
    // (both scans without branches: which block and which node come next is data the predictor cannot learn)
    int block = -1;
    double k = kInf;
    for (int b = 0; b < blocks; ++b) {
      const bool less = block_min[b] < k;
      k = less ? block_min[b] : k;
      block = less ? b : block;
    }
    if (block < 0 || k >= best) break;
    unsigned equal = 0;
    for (int j = 0; j < kKeyBlock; ++j) equal |= static_cast<unsigned>(key[block * kKeyBlock + j] == k) << j;
    const int i = block * kKeyBlock + __builtin_ctz(equal);
    const bool from_start = start_key[i] <= graph_key[i];
    const Vec2 p = node[i];
    if (from_start && !segment_clear(walls, obs, start, p, c_start)) {
      start_key[i] = kInf;
      key[i] = graph_key[i];
      refresh_block(key, block_min, i);
      continue;
    }
    const double gi = from_start ? start_g[i] : graph_g[i];
    key[i] = kInf;
    refresh_block(key, block_min, i);
    prev[i] = from_start ? -1 : graph_pred[i];
    graph_key[i] = -kInf;  // settled: no way through the graph improves on it
    if (gi + to_goal[i] < best && segment_clear(walls, obs, p, goal, c_goal)) {
      best = gi + to_goal[i];
      last = i;
    }
    for (int e = first[i]; e < first[i + 1]; ++e) {
      const int j = neighbour[e];
      const double gj = gi + length[e];
      const double kj = gj + to_goal[j];
      if (kj < graph_key[j] && kj < best) {
        graph_key[j] = kj;
        graph_g[j] = gj;
        graph_pred[j] = i;
        if (kj < key[j]) {
          key[j] = kj;
          block_min[j / kKeyBlock] = std::min(block_min[j / kKeyBlock], kj);
        }
      }
    }
  }
  return last >= 0;
}

// The shortest route from `start` to `goal` over graph g (search_route): writes its points (the goal last)
// and returns true, or returns false where the graph joins them nowhere.
bool shortest_route(const RouteGraph& g, const ObstacleView& obs, Vec2 start, Vec2 goal, std::vector<Vec2>& points) {
  const double d = g.inflation;
  // The start's and the goal's own clearance (a point inside a solid polygon sees nothing anyway: every
  // segment out of it crosses an edge).
  const EdgeSet& walls = g.walls;
  // the direct test's pass over the edges gives the start's and the goal's clearance too
  double start_clearance, goal_clearance;
  const double direct = segment_clearance(walls, obs, start, goal, start_clearance, goal_clearance);
  const double c_start = std::max(std::min(d, start_clearance) * (1.0 - 1e-9), kMinClearance);
  const double c_goal = std::max(std::min(d, goal_clearance) * (1.0 - 1e-9), kMinClearance);
  points.clear();
  if (direct >= std::min(c_start, c_goal)) {
    points.push_back(goal);
    return true;
  }
  SearchScratch& scratch = thread_scratch();
  int last = -1;
  if (!search_route(g, start, goal, c_start, c_goal, walls, obs, scratch, last)) return false;
  for (int i = last; i >= 0; i = scratch.prev[i]) points.push_back(g.node[i]);
  std::reverse(points.begin(), points.end());
  points.push_back(goal);
  return true;
}

void fill_remaining(Route& r) {
  const size_t n = r.point.size();
  r.remaining.assign(n, 0.0);
  for (size_t k = n - 1; k-- > 0;) r.remaining[k] = r.remaining[k + 1] + norm(r.point[k + 1] - r.point[k]);
}

// The cache of graphs: the map's vertex coordinates and the inflation, as raw bytes, index the graph.
struct RouteCache {
  std::mutex lock;
  std::unordered_map<std::string, std::shared_ptr<const RouteGraph>> graphs;
  std::deque<std::string> order;  // oldest first
};

RouteCache& route_cache() {
  static RouteCache cache;
  return cache;
}

std::string cache_key(const ObstacleView& obs, double inflation) {
  std::string key;
  key.resize(sizeof(double) + static_cast<size_t>(obs.count) * (2 * sizeof(double) + 2 * sizeof(int32_t)));
  char* out = key.data();
  std::memcpy(out, &inflation, sizeof(double));
  out += sizeof(double);
  for (int i = 0; i < obs.count; ++i) {
    const ObstacleVertex& v = obs.vertex[i];
    std::memcpy(out, &v.point.x, sizeof(double));
    std::memcpy(out + sizeof(double), &v.point.y, sizeof(double));
    std::memcpy(out + 2 * sizeof(double), &v.next, sizeof(int32_t));
    std::memcpy(out + 2 * sizeof(double) + sizeof(int32_t), &v.prev, sizeof(int32_t));
    out += 2 * sizeof(double) + 2 * sizeof(int32_t);
  }
  return key;
}

}  // namespace

namespace {

// The minimum of distance(i) over i in [0, n): the distances in chunks, then their minimum, so that the
// compiler vectorises the first loop (a minimum reduction over doubles it would not, without -ffast-math).
template <class Distance>
SOCIALNAV_INLINE inline double chunked_min(int n, Distance distance) {
  constexpr int kChunk = 64;
  double d[kChunk];
  double best = kInf;
  for (int base = 0; base < n; base += kChunk) {
    const int m = std::min(kChunk, n - base);
    for (int k = 0; k < m; ++k) d[k] = distance(base + k);
    for (int k = 0; k < m; ++k) best = std::min(best, d[k]);
  }
  return best;
}

// A proper crossing of the segment a + s (b - a) and the edge p + t e: p and q = p + e on opposite sides of
// the segment's line, a and b on opposite sides of the edge's; (ax, ay) = a - p, (bx, by) = b - p, (qx, qy)
// = q - a and (abx, aby) = b - a. For doubles or, lane by lane, for Lanes: every test that asks whether a
// segment crosses an edge does this arithmetic, so that they agree to the bit.
template <class T>
SOCIALNAV_INLINE inline auto proper_crossing(T ax, T ay, T bx, T by, T qx, T qy, T ex, T ey, T abx, T aby) {
  const T s1 = aby * ax - abx * ay, s2 = abx * qy - aby * qx;
  const T s3 = ex * ay - ey * ax, s4 = ex * by - ey * bx;
  return (s1 * s2 < T{}) & (s3 * s4 < T{});
}

// The smallest squared distance between the segment [a, b] and the view's edges, 0 where one crosses it:
// branch-free over the edge arrays (a wall's return face repeats its own edge), so that the compiler
// vectorises it, with an AVX2 clone chosen at load time (no contraction: the same values either way).
SOCIALNAV_AVX2_CLONE double min_edge_distance_sq(const double* __restrict px, int n, Vec2 a, Vec2 b) {
  const double* __restrict py = px + n;
  const double* __restrict ex = px + 2 * n;
  const double* __restrict ey = px + 3 * n;
  const double* __restrict inv = px + 4 * n;
  const double abx = b.x - a.x, aby = b.y - a.y;
  const double ab_sq = abx * abx + aby * aby;
  const double inv_ab = ab_sq > 0.0 ? 1.0 / ab_sq : 0.0;
  return chunked_min(n, [&](int i) SOCIALNAV_INLINE {
    // a and b to the edge p + t e
    const double ax = a.x - px[i], ay = a.y - py[i];
    const double ta = std::min(std::max((ax * ex[i] + ay * ey[i]) * inv[i], 0.0), 1.0);
    const double dax = ax - ta * ex[i], day = ay - ta * ey[i];
    const double bx = b.x - px[i], by = b.y - py[i];
    const double tb = std::min(std::max((bx * ex[i] + by * ey[i]) * inv[i], 0.0), 1.0);
    const double dbx = bx - tb * ex[i], dby = by - tb * ey[i];
    // the edge's ends p and q = p + e to the segment a + s (b - a)
    const double sp = std::min(std::max((-ax * abx - ay * aby) * inv_ab, 0.0), 1.0);
    const double dpx = -ax - sp * abx, dpy = -ay - sp * aby;
    const double qx = px[i] + ex[i] - a.x, qy = py[i] + ey[i] - a.y;
    const double sq = std::min(std::max((qx * abx + qy * aby) * inv_ab, 0.0), 1.0);
    const double dqx = qx - sq * abx, dqy = qy - sq * aby;
    const double dist = std::min(std::min(dax * dax + day * day, dbx * dbx + dby * dby),
                                 std::min(dpx * dpx + dpy * dpy, dqx * dqx + dqy * dqy));
    return proper_crossing(ax, ay, bx, by, qx, qy, ex[i], ey[i], abx, aby) ? 0.0 : dist;
  });
}

// min_edge_distance_sq and min_point_distance_sq over an EdgeSet's padded arrays, kEdgeLanes edges at a
// time in vector types, the running minimum kept per lane: the chunked loop above spends most of its
// instructions on a map's few edges in its scalar remainder and its separate minimum pass. Each lane
// computes what the scalar code does, operation for operation (std::min and std::max spelt out as their
// comparisons, no contraction), and the minimum of values that are never -0.0 (squares and 0.0; a NaN
// distance, from a zero-length edge, is passed over as std::min(best, d) passes it over) does not depend
// on the order it is taken in: the same doubles as min_edge_distance_sq(px, count, a, b).
//
// lane_edge_distances_sq gives the segment's squared distance and, with kEnds, a's and b's alone (the
// point terms of the segment's distance are min_point_distance_sq's, operation for operation): an
// agent's own clearance comes with its first segment test. With `stop_sq` > 0 it may return early, a
// squared segment distance below stop_sq, once the edges seen so far are that close.
struct SegmentDistances {
  double segment, a, b;
};
template <bool kEnds>
SOCIALNAV_INLINE inline SegmentDistances lane_edge_distances_sq(const double* __restrict px, int stride, Vec2 a, Vec2 b,
                                                                double stop_sq = 0.0) {
  const double* __restrict py = px + stride;
  const double* __restrict ex_ = px + 2 * stride;
  const double* __restrict ey_ = px + 3 * stride;
  const double* __restrict inv_ = px + 4 * stride;
  const double abx_ = b.x - a.x, aby_ = b.y - a.y;
  const double ab_sq = abx_ * abx_ + aby_ * aby_;
  const double inv_ab_ = ab_sq > 0.0 ? 1.0 / ab_sq : 0.0;
  const Lanes abx = lanes_of(abx_), aby = lanes_of(aby_), inv_ab = lanes_of(inv_ab_);
  const Lanes zero = lanes_of(0.0);
  Lanes best = lanes_of(kInf), best_a = best, best_b = best;
  for (int i = 0; i < stride; i += kEdgeLanes) {
    const Lanes x = load_lanes(px + i), y = load_lanes(py + i);
    const Lanes ex = load_lanes(ex_ + i), ey = load_lanes(ey_ + i), inv = load_lanes(inv_ + i);
    const Lanes ax = a.x - x, ay = a.y - y;
    const Lanes ta = clamp01((ax * ex + ay * ey) * inv);
    const Lanes dax = ax - ta * ex, day = ay - ta * ey;
    const Lanes bx = b.x - x, by = b.y - y;
    const Lanes tb = clamp01((bx * ex + by * ey) * inv);
    const Lanes dbx = bx - tb * ex, dby = by - tb * ey;
    const Lanes sp = clamp01((-ax * abx - ay * aby) * inv_ab);
    const Lanes dpx = -ax - sp * abx, dpy = -ay - sp * aby;
    const Lanes qx = x + ex - a.x, qy = y + ey - a.y;
    const Lanes sq = clamp01((qx * abx + qy * aby) * inv_ab);
    const Lanes dqx = qx - sq * abx, dqy = qy - sq * aby;
    const Lanes da = dax * dax + day * day, db = dbx * dbx + dby * dby;
    const Lanes dist = lane_min(lane_min(da, db), lane_min(dpx * dpx + dpy * dpy, dqx * dqx + dqy * dqy));
    best = lane_min(best, proper_crossing(ax, ay, bx, by, qx, qy, ex, ey, abx, aby) ? zero : dist);
    if (kEnds) {
      best_a = lane_min(best_a, da);
      best_b = lane_min(best_b, db);
    }
    if (stop_sq > 0.0 && i + kEdgeLanes < stride && lanes_min(best) < stop_sq) break;
  }
  return {lanes_min(best), kEnds ? lanes_min(best_a) : kInf, kEnds ? lanes_min(best_b) : kInf};
}

SOCIALNAV_AVX512_CLONE double lane_edge_distance_sq(const double* __restrict px, int stride, Vec2 a, Vec2 b) {
  return lane_edge_distances_sq<false>(px, stride, a, b).segment;
}

// sqrt(lane_edge_distance_sq(px, stride, a, b)) >= c, answered as soon as the edges seen so far are closer
// than c (the square root is monotone: the minimum can only fall further). The squares are compared where
// that decides (c^2 with a relative margin of 1e-12, far above its rounding), the root taken only in between:
// the same answer as the root's, without its latency on most tests.
SOCIALNAV_INLINE inline bool lane_edges_clear_body(const double* __restrict px, int stride, Vec2 a, Vec2 b, double c) {
  const double c_sq = c * c;
  const double below = c_sq * (1.0 - 1e-12), above = c_sq * (1.0 + 1e-12);
  const double d_sq = lane_edge_distances_sq<false>(px, stride, a, b, below).segment;
  if (d_sq < below) return false;
  if (d_sq >= above) return true;
  return std::sqrt(d_sq) >= c;
}

SOCIALNAV_AVX512_CLONE bool lane_edges_clear(const double* __restrict px, int stride, Vec2 a, Vec2 b, double c) {
  return lane_edges_clear_body(px, stride, a, b, c);
}

SOCIALNAV_AVX512_CLONE SegmentDistances lane_edge_end_distances_sq(const double* __restrict px, int stride, Vec2 a,
                                                                   Vec2 b) {
  return lane_edge_distances_sq<true>(px, stride, a, b);
}

// lane_point_distance_sq's body, outside the cloned function as lane_edge_distances_sq is (see Lanes: Clang
// refuses lane helpers called straight from an AVX2 clone).
SOCIALNAV_INLINE inline double lane_point_distance_sq_body(const double* __restrict px, int stride, Vec2 p) {
  const double* __restrict py = px + stride;
  const double* __restrict ex_ = px + 2 * stride;
  const double* __restrict ey_ = px + 3 * stride;
  const double* __restrict inv_ = px + 4 * stride;
  Lanes best = lanes_of(kInf);
  for (int i = 0; i < stride; i += kEdgeLanes) {
    const Lanes ex = load_lanes(ex_ + i), ey = load_lanes(ey_ + i);
    const Lanes tx = p.x - load_lanes(px + i), ty = p.y - load_lanes(py + i);
    const Lanes r = clamp01((tx * ex + ty * ey) * load_lanes(inv_ + i));
    const Lanes dx = tx - r * ex, dy = ty - r * ey;
    best = lane_min(best, dx * dx + dy * dy);
  }
  return lanes_min(best);
}

SOCIALNAV_AVX512_CLONE double lane_point_distance_sq(const double* __restrict px, int stride, Vec2 p) {
  return lane_point_distance_sq_body(px, stride, p);
}

// The kernels above as the baseline build runs them (not cloned: the target's default instructions), for
// route_kernel_values.
__attribute__((noinline)) std::array<double, 6> baseline_kernel_values(const double* px, int stride, Vec2 a, Vec2 b,
                                                                       double c) {
  const SegmentDistances d = lane_edge_distances_sq<true>(px, stride, a, b);
  return {d.segment,
          d.a,
          d.b,
          lane_edge_distances_sq<false>(px, stride, a, b).segment,
          lane_point_distance_sq_body(px, stride, a),
          lane_edges_clear_body(px, stride, a, b, c) ? 1.0 : 0.0};
}

}  // namespace

std::array<double, 6> route_kernel_values(const EdgeSet& edges, Vec2 a, Vec2 b, double c, bool baseline) {
  if (edges.count == 0) throw std::invalid_argument("route_kernel_values: a map without edges");
  const double* px = edges.soa.data();
  if (baseline) return baseline_kernel_values(px, edges.stride, a, b, c);
  const SegmentDistances d = lane_edge_end_distances_sq(px, edges.stride, a, b);
  return {d.segment,
          d.a,
          d.b,
          lane_edge_distance_sq(px, edges.stride, a, b),
          lane_point_distance_sq(px, edges.stride, a),
          lane_edges_clear(px, edges.stride, a, b, c) ? 1.0 : 0.0};
}

double segment_clearance(const ObstacleView& obstacles, Vec2 a, Vec2 b) {
  if (obstacles.count == 0) return kInf;
  const double best = obstacles.edges ? std::sqrt(min_edge_distance_sq(obstacles.edges, obstacles.count, a, b))
                                      : std::max(swept_obstacle_clearance(obstacles, a, b, 0.0), 0.0);
  // Clear of every edge, the segment lies inside or outside each solid polygon as a whole.
  return best > 0.0 && inside_solid(obstacles, b) ? 0.0 : best;
}

EdgeSet compact_edges(const ObstacleView& obstacles) { return compact_edges(obstacles, 0, obstacles.count); }

EdgeSet compact_edges(const ObstacleView& obstacles, int begin, int end) {
  EdgeSet e;
  std::vector<ObstacleVertex> own;
  for (int i = begin; i < end; ++i) {
    const ObstacleVertex& v = obstacles.vertex[i];
    e.has_solid = e.has_solid || v.solid;
    if (v.own_edge) own.push_back(v);
  }
  e.count = static_cast<int>(own.size());
  if (e.count > 0)
    while (own.size() % kEdgeLanes != 0) own.push_back(own.front());
  e.stride = static_cast<int>(own.size());
  e.soa.resize(5 * own.size());
  build_edge_arrays(own.data(), e.stride, e.soa.data());
  return e;
}

namespace {

// Whether the segment [a, b] properly crosses edge i of `edges`: lane_edge_distances_sq's crossing test for
// that edge alone (a crossing makes the segment's distance 0 there, whatever the other edges).
bool crosses_edge(const EdgeSet& edges, int i, Vec2 a, Vec2 b) {
  const double* px = edges.soa.data();
  const int n = edges.stride;
  const double x = px[i], y = px[n + i], ex = px[2 * n + i], ey = px[3 * n + i];
  return proper_crossing(a.x - x, a.y - y, b.x - x, b.y - y, x + ex - a.x, y + ey - a.y, ex, ey, b.x - a.x, b.y - a.y);
}

// The first edge the segment [a, b] properly crosses, -1 where it crosses none.
int crossing_edge(const EdgeSet& edges, Vec2 a, Vec2 b) {
  for (int i = 0; i < edges.count; ++i)
    if (crosses_edge(edges, i, a, b)) return i;
  return -1;
}

}  // namespace

double segment_clearance(const EdgeSet& edges, const ObstacleView& obstacles, Vec2 a, Vec2 b) {
  if (edges.count == 0) return kInf;
  const double best = std::sqrt(lane_edge_distance_sq(edges.soa.data(), edges.stride, a, b));
  return best > 0.0 && edges.has_solid && inside_solid(obstacles, b) ? 0.0 : best;
}

bool segment_clear(const EdgeSet& edges, const ObstacleView& obstacles, Vec2 a, Vec2 b, double c) {
  // segment_clearance >= c > 0 is a distance >= c and an end outside the solid polygons
  if (edges.count == 0) return kInf >= c;
  return lane_edges_clear(edges.soa.data(), edges.stride, a, b, c) && !(edges.has_solid && inside_solid(obstacles, b));
}

double segment_clearance(const EdgeSet& edges, const ObstacleView& obstacles, Vec2 a, Vec2 b, double& a_clearance,
                         double& b_clearance) {
  if (edges.count == 0) {
    a_clearance = b_clearance = kInf;
    return kInf;
  }
  const SegmentDistances d = lane_edge_end_distances_sq(edges.soa.data(), edges.stride, a, b);
  a_clearance = std::sqrt(d.a);
  b_clearance = std::sqrt(d.b);
  const double best = std::sqrt(d.segment);
  return best > 0.0 && edges.has_solid && inside_solid(obstacles, b) ? 0.0 : best;
}

namespace {

SOCIALNAV_AVX2_CLONE double min_point_distance_sq(const double* __restrict px, int n, Vec2 p) {
  const double* __restrict py = px + n;
  const double* __restrict ex = px + 2 * n;
  const double* __restrict ey = px + 3 * n;
  const double* __restrict inv = px + 4 * n;
  return chunked_min(n, [&](int i) SOCIALNAV_INLINE {
    const double tx = p.x - px[i], ty = p.y - py[i];
    const double r = std::min(std::max((tx * ex[i] + ty * ey[i]) * inv[i], 0.0), 1.0);
    const double dx = tx - r * ex[i], dy = ty - r * ey[i];
    return dx * dx + dy * dy;
  });
}

}  // namespace

double edge_clearance(const ObstacleView& obstacles, Vec2 p) {
  if (obstacles.count == 0) return kInf;
  if (!obstacles.edges) return obstacle_clearance(obstacles, p);
  return std::sqrt(min_point_distance_sq(obstacles.edges, obstacles.count, p));
}

double edge_clearance(const EdgeSet& edges, Vec2 p) {
  return edges.count == 0 ? kInf : std::sqrt(lane_point_distance_sq(edges.soa.data(), edges.stride, p));
}

double obstacle_clearance(const ObstacleView& obstacles, Vec2 p) {
  if (obstacles.count == 0) return kInf;
  return std::max(swept_obstacle_clearance(obstacles, p, p, 0.0), 0.0);
}

namespace {

// The corners of vertices [begin, end) that keep the inflation from every obstacle of the map, appended.
void add_corner_nodes(const ObstacleView& obstacles, int begin, int end, double inflation, std::vector<Vec2>& nodes) {
  std::vector<Vec2> candidates;
  for (int i = begin; i < end; ++i) corner_nodes(obstacles, i, inflation, candidates);
  for (const Vec2& c : candidates)
    if (obstacle_clearance(obstacles, c) >= inflation) nodes.push_back(c);
}

// The nodes' coordinates again, as two arrays (the search's first pass reads them).
void store_node_arrays(RouteGraph& g) {
  for (const Vec2& p : g.node) {
    g.node_x.push_back(p.x);
    g.node_y.push_back(p.y);
  }
}

// The adjacency lists (each in increasing neighbour order) as the graph's compressed rows.
void store_adjacency(RouteGraph& g, const std::vector<std::vector<std::pair<int, double>>>& adjacent) {
  const int n = static_cast<int>(adjacent.size());
  g.first.assign(static_cast<size_t>(n) + 1, 0);
  for (int i = 0; i < n; ++i) {
    g.first[i + 1] = g.first[i] + static_cast<int32_t>(adjacent[i].size());
    for (const auto& [j, len] : adjacent[i]) {
      g.neighbour.push_back(j);
      g.length.push_back(len);
    }
  }
}

}  // namespace

RouteGraph build_route_graph(const ObstacleView& obstacles, double inflation) {
  RouteGraph g;
  g.inflation = inflation;
  g.walls = compact_edges(obstacles);
  add_corner_nodes(obstacles, 0, obstacles.count, inflation, g.node);
  const int n = static_cast<int>(g.node.size());
  store_node_arrays(g);
  std::vector<std::vector<std::pair<int, double>>> adjacent(static_cast<size_t>(n));
  // segment_clearance(obstacles, a, b) >= c over the compact edges, stopping at the first edge closer than c:
  // most pairs of a large map's nodes are hidden, and the graph has one test per pair
  const double c = std::max(inflation * (1.0 - 1e-9), kMinClearance);
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j)
      if (segment_clear(g.walls, obstacles, g.node[i], g.node[j], c)) {
        const double len = norm(g.node[j] - g.node[i]);
        adjacent[i].emplace_back(j, len);
        adjacent[j].emplace_back(i, len);
      }
  store_adjacency(g, adjacent);
  return g;
}

RouteGraph build_route_graph_around(const RouteGraph& walls_graph, const ObstacleView& obstacles, int wall_vertices,
                                    double inflation) {
  // build_route_graph(obstacles, inflation), the same graph, from the walls' one: a node's clearance is the
  // least of the walls' and the added polygons', a segment is clear where it is clear of both (the square
  // root is monotone), and a kept node lies in no solid polygon (its clearance is >= the inflation > 0), so
  // the end-point test of segment_clear never fires on one. The walls' nodes come first, in their order,
  // then the added polygons' corners, as the full build lists them; pairs are tested in the same order.
  RouteGraph g;
  g.inflation = inflation;
  g.walls = compact_edges(obstacles);
  const EdgeSet added = compact_edges(obstacles, wall_vertices, obstacles.count);
  const int base_n = static_cast<int>(walls_graph.node.size());
  std::vector<int> old_index;  // a kept wall node's index in walls_graph
  for (int k = 0; k < base_n; ++k) {
    // obstacle_clearance over the added polygons alone (a wall node keeps the inflation from the walls)
    const Vec2 p = walls_graph.node[k];
    if (swept_obstacle_clearance(obstacles, p, p, 0.0, wall_vertices, obstacles.count) >= inflation) {
      g.node.push_back(p);
      old_index.push_back(k);
    }
  }
  const int kept = static_cast<int>(g.node.size());
  add_corner_nodes(obstacles, wall_vertices, obstacles.count, inflation, g.node);
  const int n = static_cast<int>(g.node.size());
  store_node_arrays(g);
  std::vector<std::vector<std::pair<int, double>>> adjacent(static_cast<size_t>(n));
  const double c = std::max(inflation * (1.0 - 1e-9), kMinClearance);
  std::vector<uint8_t> wall_neighbour(static_cast<size_t>(base_n), 0);
  for (int i = 0; i < n; ++i) {
    if (i < kept) {  // the walls' graph says which wall nodes i sees among the walls
      const int o = old_index[i];
      for (int e = walls_graph.first[o]; e < walls_graph.first[o + 1]; ++e)
        wall_neighbour[walls_graph.neighbour[e]] = 1;
    }
    for (int j = i + 1; j < n; ++j) {
      const bool visible =
          j < kept ? wall_neighbour[old_index[j]] &&
                         (added.count == 0 || lane_edges_clear(added.soa.data(), added.stride, g.node[i], g.node[j], c))
                   : segment_clear(g.walls, obstacles, g.node[i], g.node[j], c);
      if (visible) {
        const double len = norm(g.node[j] - g.node[i]);
        adjacent[i].emplace_back(j, len);
        adjacent[j].emplace_back(i, len);
      }
    }
    if (i < kept) {
      const int o = old_index[i];
      for (int e = walls_graph.first[o]; e < walls_graph.first[o + 1]; ++e)
        wall_neighbour[walls_graph.neighbour[e]] = 0;
    }
  }
  store_adjacency(g, adjacent);
  return g;
}

std::shared_ptr<const RouteGraph> cached_route_graph(const ObstacleView& obstacles, double inflation) {
  RouteCache& cache = route_cache();
  std::string key = cache_key(obstacles, inflation);
  std::lock_guard<std::mutex> guard(cache.lock);
  auto found = cache.graphs.find(key);
  if (found != cache.graphs.end()) return found->second;
  auto graph = std::make_shared<const RouteGraph>(build_route_graph(obstacles, inflation));
  if (static_cast<int>(cache.order.size()) >= kRouteCacheMaps) {
    cache.graphs.erase(cache.order.front());
    cache.order.pop_front();
  }
  cache.order.push_back(key);
  cache.graphs.emplace(std::move(key), graph);
  return graph;
}

int route_cache_size() {
  RouteCache& cache = route_cache();
  std::lock_guard<std::mutex> guard(cache.lock);
  return static_cast<int>(cache.graphs.size());
}

void clear_route_cache() {
  RouteCache& cache = route_cache();
  std::lock_guard<std::mutex> guard(cache.lock);
  cache.graphs.clear();
  cache.order.clear();
}

namespace {

double route_length_from(const Route& r, Vec2 start) { return norm(r.point[0] - start) + r.remaining[0]; }

// plan_route's rule over the graphs of inflation radius + clearance and radius (graph(d) gives them): the
// wider route, unless a narrower passage saves more than a fifth of its length (kNarrowDetour); none
// (the goal alone, found false) where neither graph joins start and goal.
template <class GraphFor>
void plan_with_tiers(const ObstacleView& obstacles, GraphFor graph, Vec2 start, Vec2 goal, double radius,
                     double clearance, Route& out) {
  out.found = shortest_route(graph(radius + clearance), obstacles, start, goal, out.point);
  out.inflation = radius + clearance;
  if (out.found) fill_remaining(out);
  // A narrower passage is looked for only where it could save a fifth: no route, or one longer than a fifth
  // more than the straight line (a goal in sight is the route).
  if (clearance > 0.0 && (!out.found || route_length_from(out, start) > kNarrowDetour * norm(goal - start))) {
    thread_local Route narrow;
    narrow.found = shortest_route(graph(radius), obstacles, start, goal, narrow.point);
    if (narrow.found) {
      narrow.inflation = radius;
      fill_remaining(narrow);
      if (!out.found || route_length_from(out, start) > kNarrowDetour * route_length_from(narrow, start)) {
        std::swap(out, narrow);
        return;
      }
    }
  }
  if (!out.found) {
    out.point.assign(1, goal);
    out.inflation = radius;
    fill_remaining(out);
  }
}

}  // namespace

void plan_route(const ObstacleView& obstacles, Vec2 start, Vec2 goal, double radius, double clearance, Route& out) {
  std::shared_ptr<const RouteGraph> wide, narrow;
  auto graph = [&](double d) -> const RouteGraph& {
    std::shared_ptr<const RouteGraph>& held = d == radius + clearance ? wide : narrow;
    if (!held) held = cached_route_graph(obstacles, d);
    return *held;
  };
  plan_with_tiers(obstacles, graph, start, goal, radius, clearance, out);
}

namespace {

// The flat polygons (vertices, offsets) of a prepared map: its polygons end where a vertex's successor
// comes before it; a wall segment's return face a -> b -> a gives its two points.
void append_flat(const ObstacleView& walls, std::vector<double>& vertices, std::vector<int64_t>& offsets) {
  for (int i = 0; i < walls.count; ++i) {
    vertices.push_back(walls.vertex[i].point.x);
    vertices.push_back(walls.vertex[i].point.y);
    if (walls.vertex[i].next <= i) offsets.push_back(static_cast<int64_t>(vertices.size() / 2));
  }
}

// The map of the walls and the n discs as regular octagons (the walls' vertices first, as they are).
PreparedObstacles walls_and_discs(const ObstacleView& walls, const Vec2* centres, const double* radii, int n) {
  thread_local std::vector<double> vertices;
  thread_local std::vector<int64_t> offsets;
  vertices.clear();
  offsets.assign(1, 0);
  append_flat(walls, vertices, offsets);
  // Counter-clockwise regular octagons around the discs (vertices 1 / cos(pi / 8) = 1.082 radii out, so
  // that the edges touch the circle): close to the disc, so that a passage a person leaves beside it stays
  // open to the planner.
  const double reach = 1.0 / std::cos(M_PI / 8.0);
  for (int k = 0; k < n; ++k) {
    for (int j = 0; j < 8; ++j) {
      const double a = M_PI / 8.0 + j * M_PI / 4.0;
      vertices.push_back(centres[k].x + reach * radii[k] * std::cos(a));
      vertices.push_back(centres[k].y + reach * radii[k] * std::sin(a));
    }
    offsets.push_back(static_cast<int64_t>(vertices.size() / 2));
  }
  return prepare_obstacles(vertices.data(), offsets.data(), static_cast<int>(offsets.size()) - 1);
}

}  // namespace

void plan_route_around(const ObstacleView& walls, const Vec2* centres, const double* radii, int n, Vec2 start,
                       Vec2 goal, double radius, double clearance, Route& out) {
  if (n == 0) {
    plan_route(walls, start, goal, radius, clearance, out);
    return;
  }
  const PreparedObstacles map = walls_and_discs(walls, centres, radii, n);
  const ObstacleView view = map.view();
  RouteGraph held;
  // the walls' graph (cached: the walls stay, the people standing change from call to call) with the
  // octagons added: the graph build_route_graph(view, d) would build, for a fraction of its tests
  auto graph = [&](double d) -> const RouteGraph& {
    held = walls.count > 0 ? build_route_graph_around(*cached_route_graph(walls, d), view, walls.count, d)
                           : build_route_graph(view, d);
    return held;
  };
  plan_with_tiers(view, graph, start, goal, radius, clearance, out);
  if (!out.found) plan_route(walls, start, goal, radius, clearance, out);
}

bool route_graph_around_matches(const ObstacleView& walls, const Vec2* centres, const double* radii, int n,
                                double inflation) {
  const PreparedObstacles map = walls_and_discs(walls, centres, radii, n);
  const ObstacleView view = map.view();
  const RouteGraph full = build_route_graph(view, inflation);
  const RouteGraph around =
      build_route_graph_around(*cached_route_graph(walls, inflation), view, walls.count, inflation);
  auto same_nodes = [](const std::vector<Vec2>& a, const std::vector<Vec2>& b) {
    if (a.size() != b.size()) return false;
    for (size_t k = 0; k < a.size(); ++k)  // bit for bit (== would also take -0.0 for 0.0)
      if (std::memcmp(&a[k], &b[k], sizeof(Vec2)) != 0) return false;
    return true;
  };
  return view.count > walls.count && same_nodes(full.node, around.node) && full.first == around.first &&
         full.neighbour == around.neighbour &&
         std::memcmp(full.length.data(), around.length.data(), full.length.size() * sizeof(double)) == 0 &&
         full.length.size() == around.length.size();
}

namespace {

// heading_point with the agent's distance to w, norm(w - position), given.
inline Vec2 heading_point_at(bool last_leg, Vec2 w, double w_remaining, Vec2 next, Vec2 position, Vec2 goal,
                             double to_point) {
  if (last_leg) return goal;
  if (to_point < 1e-9) return next;
  return position + ((to_point + w_remaining) / to_point) * (w - position);
}

}  // namespace

Vec2 heading_point(bool last_leg, Vec2 w, double w_remaining, Vec2 next, Vec2 position, Vec2 goal) {
  return heading_point_at(last_leg, w, w_remaining, next, position, goal, last_leg ? 0.0 : norm(w - position));
}

Vec2 heading_point(const Route& route, int index, Vec2 position, Vec2 goal) {
  if (!route.found || index + 1 >= static_cast<int>(route.point.size())) return goal;
  return heading_point(false, route.point[index], route.remaining[index], route.point[index + 1], position, goal);
}

void route_distances(const ObstacleView& obstacles, const Vec2* points, int n, Vec2 goal, double radius, double* out) {
  if (obstacles.count == 0) {
    for (int k = 0; k < n; ++k) out[k] = norm(goal - points[k]);
    return;
  }
  const auto graph = cached_route_graph(obstacles, radius);
  const RouteGraph& g = *graph;
  const int m = static_cast<int>(g.node.size());
  const double c_goal = std::max(std::min(radius, obstacle_clearance(obstacles, goal)) * (1.0 - 1e-9), kMinClearance);
  // Dijkstra from the goal: to_goal[i], node i's route length to the goal.
  std::vector<double> to_goal(static_cast<size_t>(m), kInf);
  struct Candidate {
    double distance;
    int node;
    bool operator>(const Candidate& o) const {
      return distance > o.distance || (distance == o.distance && node > o.node);
    }
  };
  std::priority_queue<Candidate, std::vector<Candidate>, std::greater<Candidate>> open;
  for (int i = 0; i < m; ++i)
    if (segment_clearance(g.walls, obstacles, g.node[i], goal) >= c_goal) {
      to_goal[i] = norm(goal - g.node[i]);
      open.push({to_goal[i], i});
    }
  while (!open.empty()) {
    const Candidate c = open.top();
    open.pop();
    if (c.distance > to_goal[c.node]) continue;
    for (int k = g.first[c.node]; k < g.first[c.node + 1]; ++k) {
      const int j = g.neighbour[k];
      const double dj = c.distance + g.length[k];
      if (dj < to_goal[j]) {
        to_goal[j] = dj;
        open.push({dj, j});
      }
    }
  }
  for (int k = 0; k < n; ++k) {
    const Vec2 p = points[k];
    const double c_point = std::max(std::min(radius, obstacle_clearance(obstacles, p)) * (1.0 - 1e-9), kMinClearance);
    if (segment_clearance(g.walls, obstacles, p, goal) >= std::min(c_point, c_goal)) {
      out[k] = norm(goal - p);
      continue;
    }
    double best = kInf;
    for (int i = 0; i < m; ++i) {
      const double via = norm(g.node[i] - p) + to_goal[i];
      if (via < best && segment_clearance(g.walls, obstacles, p, g.node[i]) >= c_point) best = via;
    }
    out[k] = best;
  }
}

void RouteFollower::plan(const ObstacleView& obstacles, Vec2 start, Vec2 goal, double radius, double clearance,
                         const std::shared_ptr<const PreparedObstacles>& map) {
  if (!map || map != held_map) {  // another map (or one not known): its graphs are looked up afresh
    wide_graph.reset();
    narrow_graph.reset();
    held_map = map;
  }
  start_over(obstacles, start, goal, radius, clearance);
  replans = 0;
}

void RouteFollower::start_over(const ObstacleView& obstacles, Vec2 start, Vec2 goal, double radius, double clearance) {
  replan(obstacles, start, goal, radius, clearance);
  yields = 0;
  best_remaining = kInf;
  stalled = 0.0;
  yielding = 0.0;
  last_step = -1;
}

void RouteFollower::replan(const ObstacleView& obstacles, Vec2 start, Vec2 goal, double radius, double clearance) {
  // The episode's graphs are looked up once and kept: a re-plan costs the search only.
  auto graph = [&](double d) -> const RouteGraph& {
    std::shared_ptr<const RouteGraph>& held = d == radius + clearance ? wide_graph : narrow_graph;
    if (!held) held = cached_route_graph(obstacles, d);
    return *held;
  };
  plan_with_tiers(obstacles, graph, start, goal, radius, clearance, route);
  index = 0;
  seen_margin = blocked_margin = -1.0;
  blocking = -1;  // an edge index of the map planned on before: past the end of a map with fewer edges
  sync();
}

void RouteFollower::sync() {
  const int n = static_cast<int>(route.point.size());
  points = route.found ? n : 0;
  inflation = route.inflation;
  if (index < 0 || index >= n) return;  // (no route yet)
  aim = route.point[index];
  aim_remaining = route.remaining[index];
  next_aim = index + 1 < n ? route.point[index + 1] : aim;
}

Vec2 RouteFollower::target(const ObstacleView& obstacles, Vec2 position, Vec2 goal, double radius, double clearance,
                           int step, double dt, int agent) {
  double to_aim = 0.0;  // norm(aim - position), once for the three uses
  const Vec2 ahead = route_target(obstacles, position, goal, radius, clearance, to_aim);
  if (points == 0) return ahead;
  const double remaining = to_aim + aim_remaining;
  if (step != last_step) {
    last_step = step;
    if (yielding > 0.0) {
      yielding -= dt;
    } else if (remaining <= radius) {  // arrived: waiting at the goal is no stall
      stalled = 0.0;
      best_remaining = remaining;
    } else if (remaining < best_remaining - kProgress) {
      best_remaining = remaining;
      stalled = 0.0;
    } else if ((stalled += dt) >= kPatience) {
      yielding = kYieldTimes[(agent + yields) % 4];
      ++yields;
      stalled = 0.0;
      best_remaining = kInf;  // progress is measured afresh after giving way
    }
  }
  if (yielding <= 0.0) return ahead;
  const Vec2 away = position - aim;
  const double len = to_aim;  // (norm(away): the same squares)
  return len > 1e-9 ? position + (1.0 / len) * away : ahead;
}

Vec2 RouteFollower::route_target(const ObstacleView& obstacles, Vec2 position, Vec2 goal, double radius,
                                 double clearance, double& to_aim) {
  if (points == 0) return goal;              // no route: straight for the goal
  const EdgeSet& walls = wide_graph->walls;  // planned: the graph is held
  const int n = points;
  // The two tests below are skipped where their answer is known from an earlier step: a segment's clearance,
  // and the agent's own, change by at most as much as the agent moved (both are 1-Lipschitz in its position).
  bool advanced = false;
  double own = -1.0;  // the agent's own clearance, computed when a test needs it
  // (the distance moved compared in squares, with a margin far above their rounding: no root taken)
  if (index + 1 < n &&
      !(blocked_margin > 0.0 && abs_sq(position - blocked_from) < blocked_margin * blocked_margin * (1.0 - 1e-12)) &&
      !(blocking >= 0 && crosses_edge(walls, blocking, position, next_aim))) {
    // (Above: the next point is still hidden where the segment to it crosses the wall edge that hid it
    // last time: its distance is 0, below any c_advance, so the full test would find it hidden too.)
    // Advance to the farthest point seen with half the planned clearance, or with the agent's own where a
    // neighbour pressed it closer to a wall than that, or, on the last leg, with the goal's own where the goal
    // lies closer to a wall than that (the world keeps goals only a radius from the walls; the search plans
    // the last leg with the goal's clearance alike): a goal could never be seen otherwise.
    double next_clearance;
    double seen = segment_clearance(walls, obstacles, position, next_aim, own, next_clearance);
    const double c_wide = std::max(0.5 * (radius + inflation), kMinClearance);
    double c_advance = std::max(std::min(c_wide, 0.99 * own), kMinClearance);
    if (index + 2 == n) c_advance = std::max(std::min(c_advance, 0.99 * next_clearance), kMinClearance);
    for (;;) {
      if (seen < c_advance) {
        // Hidden: it stays hidden while the agent moves less than this (the segment gains at most the
        // distance moved, c_advance loses at most 0.99 of it); where the agent is far enough from the walls
        // that c_advance stays c_wide (0.99 of its own clearance, which loses at most the distance moved,
        // above c_wide), while it moves less than c_wide - seen.
        blocked_from = position;
        blocked_margin = (c_advance - seen) / 1.99;
        if (c_advance == c_wide)
          blocked_margin = std::max(blocked_margin, (1.0 - 1e-9) * std::min(c_wide - seen, own - c_wide / 0.99));
        blocking = seen == 0.0 ? crossing_edge(walls, position, advanced ? route.point[index + 1] : next_aim) : -1;
        break;
      }
      ++index;
      advanced = true;
      blocked_margin = -1.0;
      seen_from = position;
      seen_margin = seen - std::max(0.99 * radius, kMinClearance);
      if (index + 1 == n) break;
      if (index + 2 == n) {  // the goal next: its own clearance may lower the bar (above)
        double here;
        seen = segment_clearance(walls, obstacles, position, route.point[index + 1], here, next_clearance);
        c_advance = std::max(std::min(c_advance, 0.99 * next_clearance), kMinClearance);
      } else {
        seen = segment_clearance(walls, obstacles, position, route.point[index + 1]);
      }
    }
    if (advanced) sync();
  }
  // Pushed off the route (the point it heads for, the goal included, is behind a wall, or the way to it passes
  // a wall closer than the agent's radius, or than its own clearance where it is closer): re-plan from here,
  // as on a new route (the giving-way timers start afresh). It surely still sees the point while it strays
  // less than seen_margin from the segment it saw it along: every point of the new segment is then within
  // that distance of a point of the old one.
  if (!advanced &&
      !(seen_margin >= 0.0 && dist_sq_point_segment(seen_from, aim, position) <= seen_margin * seen_margin)) {
    double seen, point_clearance;
    if (own < 0.0)
      seen = segment_clearance(walls, obstacles, position, aim, own, point_clearance);
    else
      seen = segment_clearance(walls, obstacles, position, aim);
    if (seen >= std::max(0.99 * std::min(radius, own), kMinClearance)) {
      seen_from = position;
      seen_margin = seen - std::max(0.99 * radius, kMinClearance);
    } else {
      start_over(obstacles, position, goal, radius, clearance);
      ++replans;
      if (!route.found) return goal;
    }
  }
  // (after a re-plan, a route of another length)
  to_aim = norm(aim - position);
  return heading_point_at(index + 1 >= points, aim, aim_remaining, next_aim, position, goal, to_aim);
}

}  // namespace socialnav
