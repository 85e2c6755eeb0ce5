// Routes among static obstacles: where an agent walks to reach its goal when a wall stands between
// them (docs/routes.md).
//
// Per map and inflation d (an agent's radius plus a clearance), once: a visibility graph over the
// obstacles' corners offset by d (T. Lozano-Pérez, M. A. Wesley, "An algorithm for planning collision-free
// paths among polyhedral obstacles", Commun. ACM 22(10), 1979; with the configuration-space offset of the
// same paper). Nodes sit at distance >= d from every edge, beside each convex corner (a wall's ends
// included); two nodes are joined where the straight segment between them keeps >= d from every edge. Per
// agent: the shortest route from where it stands to its goal (A* over the graph, the start and the goal
// joined to the nodes they see; of routes of exactly equal length, the one a fixed rule picks, routes.cpp's
// search_route). Per step: the agent heads for the farthest route point it sees with
// clearance (string pulling), and re-plans from where it stands once the point it heads for is hidden.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "obstacles.hpp"
#include "vec2.hpp"

namespace socialnav {

// A map's own edges (a wall's return face left out) as five arrays of `stride` doubles (point x, y, edge
// x, y, 1 / |edge|^2): what the per-step visibility and clearance tests scan. The arrays run on past
// `count` to a multiple of kEdgeLanes with copies of the first edge, so that the tests take whole vectors
// (a copy changes no minimum).
constexpr int kEdgeLanes = 4;
struct EdgeSet {
  std::vector<double> soa;
  int count = 0;
  int stride = 0;
  bool has_solid = false;  // some polygon has an interior (then a segment's end may lie inside one)
};
EdgeSet compact_edges(const ObstacleView& obstacles);
// The edges of vertices [begin, end) alone (whole polygons: a polygon's vertices are consecutive).
EdgeSet compact_edges(const ObstacleView& obstacles, int begin, int end);
// segment_clearance and edge_clearance (below) over an EdgeSet of `obstacles` (the same map).
double segment_clearance(const EdgeSet& edges, const ObstacleView& obstacles, Vec2 a, Vec2 b);
double edge_clearance(const EdgeSet& edges, Vec2 p);
// segment_clearance(edges, obstacles, a, b) >= c for c > 0, without the rest of the edges once one is closer.
bool segment_clear(const EdgeSet& edges, const ObstacleView& obstacles, Vec2 a, Vec2 b, double c);
// segment_clearance, and edge_clearance of a and of b from the same pass over the edges.
double segment_clearance(const EdgeSet& edges, const ObstacleView& obstacles, Vec2 a, Vec2 b, double& a_clearance,
                         double& b_clearance);

// One map's visibility graph for inflation d [m]: nodes and their edges (CSR: node i's neighbours are
// neighbour[first[i]..first[i + 1]), with the segment lengths), and the map's edges.
struct RouteGraph {
  double inflation = 0.0;
  EdgeSet walls;
  std::vector<Vec2> node;
  std::vector<double> node_x, node_y;  // the nodes' coordinates again, as two arrays (the search's first pass)
  std::vector<int32_t> first;
  std::vector<int32_t> neighbour;
  std::vector<double> length;
};

// Builds the graph of `obstacles` (the unsplit map) for inflation d > 0. Cost: O(V) nodes (one or two
// per convex corner), O(V^2 * E) segment tests for the edges.
RouteGraph build_route_graph(const ObstacleView& obstacles, double inflation);

// build_route_graph(obstacles, inflation), built from `walls_graph`, the graph of the map's first
// `wall_vertices` vertices alone (its walls), for the polygons after them (plan_route_around's people):
// the same nodes, edges and lengths, bit for bit, without testing again the pairs of wall nodes the walls
// already hide.
RouteGraph build_route_graph_around(const RouteGraph& walls_graph, const ObstacleView& obstacles, int wall_vertices,
                                    double inflation);

// The graph of a map with this content and inflation, built on first use and then shared (process-wide,
// thread-safe; keyed by the vertices' coordinates, so every episode with the same map shares one graph,
// and maps drawn per episode get one each). At most kRouteCacheMaps maps are kept; the oldest go first.
std::shared_ptr<const RouteGraph> cached_route_graph(const ObstacleView& obstacles, double inflation);
constexpr int kRouteCacheMaps = 4096;
// Graphs in the cache now (tests and the cost measurement read it).
int route_cache_size();
void clear_route_cache();

// What the route kernels give for the segment [a, b] over `edges` (a map with edges): the squared distances
// of the segment (0 where it crosses an edge) and of a and of b alone, the segment's again from the kernel
// without the ends, a's from the point kernel, and 1 where the segment's clearance is >= c (else 0); from the
// build the CPU's dispatch picked (x86-64-v4, AVX2 or the baseline: multiversion.hpp) or, with `baseline`,
// from the baseline build. Every build runs the same operations, so the two agree bit for bit (tested).
std::array<double, 6> route_kernel_values(const EdgeSet& edges, Vec2 a, Vec2 b, double c, bool baseline);

// The distance [m] between the segment [a, b] and the nearest obstacle edge: 0 where it crosses one or ends
// inside a solid polygon; +inf without obstacles.
double segment_clearance(const ObstacleView& obstacles, Vec2 a, Vec2 b);

// The distance from p to the nearest obstacle edge (0 inside a solid polygon; +inf without obstacles).
double obstacle_clearance(const ObstacleView& obstacles, Vec2 p);
// The same distance to the nearest edge without the inside test, over the view's edge arrays (a view with
// `edges`, as the world's and a prepared map's are): the per-step query of a route follower.
double edge_clearance(const ObstacleView& obstacles, Vec2 p);

constexpr double kNarrowDetour = 1.2;

// A planned route: the points to pass, the goal last, and the inflation it was planned with.
struct Route {
  std::vector<Vec2> point;
  std::vector<double> remaining;  // remaining[k]: route length from point k to the goal
  double inflation = 0.0;
  bool found = false;  // false: no route at any inflation (the point list is then the goal alone)
};

// Plans `start` -> `goal` for an agent of `radius` [m] keeping `clearance` [m] from the walls where it can:
// with inflation radius + clearance, or with the radius alone where that is the only way (a door narrower
// than radius + clearance) or saves more than a fifth of the length (kNarrowDetour: people squeeze through
// a narrow gap rather than walk far round), else no route (heading straight for the goal, as without
// routes). The start and goal connect to the nodes with
// min(inflation, their own clearance), so an agent already closer to a wall than d can still leave it.
void plan_route(const ObstacleView& obstacles, Vec2 start, Vec2 goal, double radius, double clearance, Route& out);

// plan_route among the walls and n standing discs (centres, radii [m]; e.g. people who do not move), each
// taken as the regular octagon around it: the global planner's obstacle layer. Its graph is the walls'
// cached one with the octagons added for this call (build_route_graph_around: the discs change from step to
// step). Where no route avoids the discs, the route among the walls alone.
void plan_route_around(const ObstacleView& walls, const Vec2* centres, const double* radii, int n, Vec2 start,
                       Vec2 goal, double radius, double clearance, Route& out);
// Whether plan_route_around's graph for inflation d (the walls' cached graph with the discs added) equals the
// full build over the walls and the discs, bit for bit (tests).
bool route_graph_around_matches(const ObstacleView& walls, const Vec2* centres, const double* radii, int n,
                                double inflation);

// The point an agent at `position` heading for point `index` of `route` hands its model's preferred-velocity
// law (behaviour.hpp): the goal on the last leg (or without a route); before, a point beyond route point
// `index` on the line to it, as far from the agent as the rest of the route is long, so that the law's
// slow-down near its target applies at the goal, not at each corner. RouteFollower::target and the
// route-following robot policies both head this way.
Vec2 heading_point(const Route& route, int index, Vec2 position, Vec2 goal);
// heading_point given route point `index` (w), its remaining length and whether it is the last leg: the same
// arithmetic, for a caller that holds them.
Vec2 heading_point(bool last_leg, Vec2 w, double w_remaining, Vec2 next, Vec2 position, Vec2 goal);

// The lengths [m] of the shortest paths of a disc of `radius` from each of n points to `goal` (the free-space
// geodesic distance: the visibility graph with inflation = radius, no clearance), written into out; inf where
// there is none. One Dijkstra from the goal serves every point, and a point that sees the goal costs one
// segment test: what the stuck detection measures progress with (docs/routes.md).
void route_distances(const ObstacleView& obstacles, const Vec2* points, int n, Vec2 goal, double radius, double* out);

// A routed agent that makes no progress gives way: after kPatience seconds in which its remaining route
// length shrank by less than kProgress, it steps back (away from the point it heads for) for a while, then
// tries again. Local models have no yielding of their own: two social-force pedestrians meeting head-on in
// a one-person door push against each other for ever (Helbing & Molnár's forces balance), and RVO2 agents
// can freeze the same way. The step-back time differs between agents and attempts (kYieldTimes, chosen by
// agent index and attempt), so that two who gave way together do not come back together.
constexpr double kProgress = 0.2;                        // [m]
constexpr double kPatience = 3.0;                        // [s]
constexpr double kYieldTimes[4] = {1.0, 2.5, 4.0, 5.5};  // [s]

// One agent following its route: which point it heads for, re-planning when that point is hidden. The
// fields a step reads come first, in the first three of its cache lines (the struct starts one): a step
// that neither advances nor re-plans touches those three lines and no others (a batch's followers are
// megabytes: each line it touches is a likely cache miss).
struct alignas(64) RouteFollower {
  // route.point[index], route.remaining[index] and route.point[index + 1] (the goal where there is none),
  // held here: a step that neither advances nor re-plans reads no route array (each follower's arrays are
  // heap blocks of their own, a cache miss apiece at a batch's scale). sync() sets them from the route.
  Vec2 aim, next_aim;
  // What the last tests showed (route_target): from seen_from the point headed for was in sight with
  // seen_margin to spare, from blocked_from the next one was hidden by blocked_margin (< 0: not known).
  Vec2 seen_from, blocked_from;
  double aim_remaining = 0.0;
  double seen_margin = -1.0, blocked_margin = -1.0;
  double best_remaining = 0.0;  // the shortest remaining route length so far [m]
  double stalled = 0.0;         // time since it last came kProgress closer [s]
  double yielding = 0.0;        // time left stepping back [s]
  int index = 0;                // the route point it heads for
  int points = 0;               // route.point.size() where a route was found, else 0 (sync() sets it)
  int last_step = -1;           // the step the timers were last advanced at
  int blocking = -1;            // a wall edge the segment to the next point crossed when last found hidden (-1: none)
  std::shared_ptr<const RouteGraph> wide_graph;       // the map's graph for radius + clearance (its walls are tested)
  double inflation = 0.0;                             // route.inflation (sync() sets it)
  int yields = 0;                                     // times it gave way
  int replans = 0;                                    // re-plans since the route was first planned
  std::shared_ptr<const RouteGraph> narrow_graph;     // the map's graph for the radius alone
  std::shared_ptr<const PreparedObstacles> held_map;  // the map they belong to (plan's `map`)
  Route route;

  // Refreshes the copies above after `route` or `index` were set from outside (a restored state).
  void sync();

  // `map`: the object that owns `obstacles` where the caller has one (the world's slot map); a follower
  // planning again on the same one keeps the graphs it holds instead of looking them up (and takes no
  // copy of `map`: every slot's followers share it, and a copy's reference count is one atomic counter
  // that all threads would write).
  void plan(const ObstacleView& obstacles, Vec2 start, Vec2 goal, double radius, double clearance,
            const std::shared_ptr<const PreparedObstacles>& map = nullptr);
  // The point to hand the behaviour's preferred-velocity law (behaviour.hpp) at step `step` of length dt
  // [s] for agent `agent`: heading_point of its route point; while giving way, a point behind it. Calls for the same
  // step (a preview, then the step) advance the timers once.
  Vec2 target(const ObstacleView& obstacles, Vec2 position, Vec2 goal, double radius, double clearance, int step,
              double dt, int agent);

 private:
  // (to_aim: set to norm(aim - position) where a route was found)
  Vec2 route_target(const ObstacleView& obstacles, Vec2 position, Vec2 goal, double radius, double clearance,
                    double& to_aim);
  // The route from `start` afresh (same map: the held graphs), index at its first point.
  void replan(const ObstacleView& obstacles, Vec2 start, Vec2 goal, double radius, double clearance);
  // replan, and the giving-way timers too: what an agent pushed off its route does.
  void start_over(const ObstacleView& obstacles, Vec2 start, Vec2 goal, double radius, double clearance);
};

}  // namespace socialnav
