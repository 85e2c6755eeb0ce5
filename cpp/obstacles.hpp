// Static obstacles of one episode: the geometry shared by ORCA, social force and the collision test.
//
// An episode's map arrives as flat polygons (socialnav.maps.StaticMap.to_flat: vertices (V, 2)
// and offsets (P + 1,)): a polygon of k >= 3 vertices is solid and counter-clockwise, a 2-vertex
// polygon is a wall segment. Each vertex is prepared the way van den Berg et al.'s obstacle
// algorithm (ISRR 2011, Sec. 5; the RVO2 library) sees it: a directed edge to its successor, its
// predecessor, and whether it is convex. A wall segment is RVO2's degenerate polygon a -> b -> a:
// two vertices, both convex, whose edges are the two faces of the wall, so it blocks from both sides.
#pragma once

#include <cstdint>
#include <vector>

#include "vec2.hpp"

namespace socialnav {

struct ObstacleVertex {
  Vec2 point;
  Vec2 unit_dir;           // towards the next vertex
  Vec2 edge;               // next point - point
  double inv_edge_len_sq;  // 1 / |edge|^2
  int32_t next;            // indices into the same episode's vertex array
  int32_t prev;
  bool convex;
  bool solid;     // belongs to a polygon with an interior (k >= 3)
  bool own_edge;  // the edge to `next` is an edge of its own (false for a wall's return face b -> a)
};

// One episode's prepared vertices (null/0 for an open floor). `edges` holds the same vertices'
// edges as five arrays of `count` doubles (point x, point y, edge x, edge y, 1 / |edge|^2): the
// structure of arrays the per-agent neighbour query scans without branches.
struct ObstacleView {
  const ObstacleVertex* vertex = nullptr;
  int count = 0;
  const double* edges = nullptr;
  // An ORCA view (OrcaObstacles) has, instead of `edges`, seven arrays of `count` doubles: point x, y,
  // edge x, y, |edge|^2, next point x, y (what RVO2's distance to a segment reads), and RVO2's
  // obstacle tree over these vertices: per vertex, the vertex
  // whose tree node is its node's parent (-1 at the root), whether its node is that parent's left child,
  // and its depth. It orders edges at equal distance from an agent as RVO2's tree query meets them; null
  // elsewhere (ties then keep vertex order).
  const double* orca_edges = nullptr;
  const int32_t* tree_parent = nullptr;
  const uint8_t* tree_is_left = nullptr;
  const int32_t* tree_depth = nullptr;
};

// The obstacles as RVO2's ORCA sees them (van den Berg et al., ISRR 2011, Sec. 5; the RVO2 library's
// obstacle kd-tree): the map's vertices, then the points where building the tree split an edge that
// crossed the line of the edge chosen at a node. A split point is a vertex of its own, convex, with the
// direction of the edge it cuts, so the velocity obstacle of each half has legs at the split point as in
// RVO2. Built once per map; collisions, social force and observations keep the unsplit map.
struct OrcaObstacles {
  std::vector<ObstacleVertex> vertex;
  std::vector<double> edges;  // build_orca_edge_arrays of vertex (7 per vertex)
  std::vector<int32_t> parent;
  std::vector<uint8_t> is_left;
  std::vector<int32_t> depth;
  ObstacleView view() const {
    return ObstacleView{
        vertex.data(), static_cast<int>(vertex.size()), nullptr, edges.data(), parent.data(), is_left.data(),
        depth.data()};
  }
};

// RVO2's split of `count` prepared vertices (indices next/prev relative to vertex[0]) and its tree.
OrcaObstacles build_orca_obstacles(const ObstacleVertex* vertex, int count);

// Writes an ORCA view's seven edge arrays of `count` vertices (ObstacleView::orca_edges, 7 * count).
void build_orca_edge_arrays(const ObstacleVertex* vertex, int count, double* edges);

// True when an agent at `position` meets the edge of vertex a before the edge of vertex b in RVO2's
// obstacle-tree query (near subtree, then the node, then the far subtree); `view` must carry a tree.
bool tree_query_precedes(const ObstacleView& view, int a, int b, Vec2 position);

// Writes `count` vertices' edge arrays (ObstacleView::edges, 5 * count doubles).
void build_edge_arrays(const ObstacleVertex* vertex, int count, double* edges);

// Prepared obstacles that own their storage (one map, or many episodes' maps back to back).
struct PreparedObstacles {
  std::vector<ObstacleVertex> vertex;
  std::vector<double> edges;  // 5 doubles per vertex, episode by episode
  OrcaObstacles orca;         // the same map as ORCA sees it
  ObstacleView view() const { return ObstacleView{vertex.data(), static_cast<int>(vertex.size()), edges.data()}; }
  ObstacleView orca_view() const { return orca.view(); }
};

// Many episodes' prepared vertices: episode b owns vertex[first[b], first[b] + count[b]) and the edge
// arrays at edges + 5 * first[b]; null for none. Episodes with the same map may share one range (the
// per-step passes then read one copy of it, which stays in cache).
struct ObstacleBatchView {
  const ObstacleVertex* vertex = nullptr;
  const double* edges = nullptr;
  const int64_t* first = nullptr;
  const int32_t* count = nullptr;
  // The same episodes' OrcaObstacles back to back (episode b at orca_first[b], orca_count[b] vertices).
  const ObstacleVertex* orca_vertex = nullptr;
  const double* orca_edges = nullptr;
  const int32_t* orca_parent = nullptr;
  const uint8_t* orca_is_left = nullptr;
  const int32_t* orca_depth = nullptr;
  const int64_t* orca_first = nullptr;
  const int32_t* orca_count = nullptr;
  ObstacleView episode(int b) const {
    if (!first) return ObstacleView{};
    return ObstacleView{vertex + first[b], count[b], edges + 5 * first[b]};
  }
  ObstacleView orca_episode(int b) const {
    if (!orca_first) return ObstacleView{};
    const int64_t f = orca_first[b];
    return ObstacleView{orca_vertex + f, orca_count[b],    nullptr,       orca_edges + 7 * f,
                        orca_parent + f, orca_is_left + f, orca_depth + f};
  }
};

// Prepares `offsets[n_polygons]` vertices from flat polygons; throws std::invalid_argument on a
// polygon of fewer than 2 vertices, a non-finite vertex or coincident consecutive vertices.
void build_obstacle_vertices(const double* vertices, const int64_t* offsets, int n_polygons, ObstacleVertex* out);

// One map prepared from flat polygons (build_obstacle_vertices + build_edge_arrays).
PreparedObstacles prepare_obstacles(const double* vertices, const int64_t* offsets, int n_polygons);

// The maps of B episodes prepared once (the native robot policies' per-step input): episode b owns
// vertex[first[b], first[b] + count[b]) and its edge arrays.
struct PreparedObstacleBatch {
  std::vector<ObstacleVertex> vertex;
  std::vector<double> edges;
  std::vector<int64_t> first;  // (B,) episode b's first vertex
  std::vector<int32_t> count;  // (B,) its vertex count
  // The episodes' maps as ORCA sees them (OrcaObstacles), back to back, shared as above.
  OrcaObstacles orca;
  std::vector<int64_t> orca_first;
  std::vector<int32_t> orca_count;
  ObstacleBatchView view() const {
    return {vertex.data(),      edges.data(),      first.data(),       count.data(),
            orca.vertex.data(), orca.edges.data(), orca.parent.data(), orca.is_left.data(),
            orca.depth.data(),  orca_first.data(), orca_count.data()};
  }
};

// Prepares B episodes' maps from flat polygons (vertices, offsets (n_polygons + 1,)) and
// episode_polygons (B + 1,): episode b has polygons [episode_polygons[b], episode_polygons[b + 1]). An
// episode whose map equals the previous episode's, bit for bit, shares its prepared vertices (a batch of
// one map, the common case, holds one copy). Throws std::invalid_argument where episode_polygons does
// not run from 0 to n_polygons without decreasing, or a polygon is malformed.
PreparedObstacleBatch prepare_obstacle_batch(const double* vertices, const int64_t* offsets, int n_polygons,
                                             const int64_t* episode_polygons, int64_t batch);

// RVO2's leftOf(a, b, c): > 0 when c lies to the left of the directed line a -> b.
inline double left_of(Vec2 a, Vec2 b, Vec2 c) { return det(a - c, b - a); }

// Squared distance from point c to segment [a, b].
inline double dist_sq_point_segment(Vec2 a, Vec2 b, Vec2 c) {
  const Vec2 ab = b - a;
  const double r = dot(c - a, ab) / abs_sq(ab);
  if (r < 0.0) return abs_sq(c - a);
  if (r > 1.0) return abs_sq(c - b);
  return abs_sq(c - (a + r * ab));
}

// Closest point of segment [a, b] to c.
inline Vec2 closest_point_segment(Vec2 a, Vec2 b, Vec2 c) {
  const Vec2 ab = b - a;
  double r = dot(c - a, ab) / abs_sq(ab);
  r = r < 0.0 ? 0.0 : (r > 1.0 ? 1.0 : r);
  return a + r * ab;
}

// Distance between segments [p0, p1] and [a, b] (0 when they cross); p0 == p1 is allowed.
double segment_segment_distance(Vec2 p0, Vec2 p1, Vec2 a, Vec2 b);

// True when c lies inside one of the solid polygons (even-odd rule; segments contain nothing).
bool inside_solid(const ObstacleView& obstacles, Vec2 c);
// inside_solid over the polygons of vertices [begin, end) alone (a polygon's vertices are consecutive).
bool inside_solid(const ObstacleView& obstacles, Vec2 c, int begin, int end);

// True when a disc of `radius` centred at c overlaps an obstacle: closer than `radius` to an edge, or
// centred inside a solid polygon (swept_disc_hits_obstacles(obstacles, c, c, radius) up to rounding at
// the boundary). The world's test of a loaded episode's starts and goals.
bool disc_touches_obstacles(const ObstacleView& obstacles, Vec2 c, double radius);

// Smallest clearance between a disc of radius `radius` whose centre moves from p0 to p1 in a straight
// line and the obstacles: min distance from the path to any edge minus the radius, or -radius where
// the path ends inside a solid polygon; +inf without obstacles. < 0 means the disc touched an
// obstacle during the move (a thin wall crossed within one step included).
double swept_obstacle_clearance(const ObstacleView& obstacles, Vec2 p0, Vec2 p1, double radius);
// swept_obstacle_clearance over the polygons of vertices [begin, end) alone: the same operations, so that the
// clearance over a whole map is the least of its parts'.
double swept_obstacle_clearance(const ObstacleView& obstacles, Vec2 p0, Vec2 p1, double radius, int begin, int end);

// swept_obstacle_clearance(obstacles, p0, p1, radius) < 0, the same answer without the distances to
// the edges whose bounding box is clearly farther than `radius` from the path's, and stopping at the
// first edge the disc touches: the world's per-step collision test.
bool swept_disc_hits_obstacles(const ObstacleView& obstacles, Vec2 p0, Vec2 p1, double radius);

}  // namespace socialnav
