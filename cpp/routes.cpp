#include "routes.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <deque>
#include <limits>
#include <mutex>
#include <queue>
#include <string>
#include <unordered_map>
#include <utility>

namespace socialnav {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// Nodes sit this factor farther than d from the edges' lines, so that the segment between two nodes of
// one edge passes the d test despite rounding.
constexpr double kNodeSlack = 1.01;
// A tested clearance never drops below this [m]: a segment through a wall has distance 0 and must fail.
constexpr double kMinClearance = 1e-6;

inline Vec2 right_normal(Vec2 u) { return Vec2{u.y, -u.x}; }

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

struct Candidate {
  double distance;
  int node;
  bool operator>(const Candidate& o) const {
    return distance > o.distance || (distance == o.distance && node > o.node);
  }
};

// Dijkstra from `start` to `goal` over graph g; writes the route's points (the goal last) and returns true,
// or returns false where the graph joins them nowhere.
bool shortest_route(const RouteGraph& g, const ObstacleView& obs, Vec2 start, Vec2 goal, std::vector<Vec2>& points) {
  const double d = g.inflation;
  const double c_start = std::max(std::min(d, obstacle_clearance(obs, start)) * (1.0 - 1e-9), kMinClearance);
  const double c_goal = std::max(std::min(d, obstacle_clearance(obs, goal)) * (1.0 - 1e-9), kMinClearance);
  points.clear();
  if (visible_with_clearance(obs, start, goal, std::min(c_start, c_goal))) {
    points.push_back(goal);
    return true;
  }
  const int n = static_cast<int>(g.node.size());
  std::vector<double> dist(static_cast<size_t>(n), kInf);
  std::vector<int> prev(static_cast<size_t>(n), -1);
  std::vector<uint8_t> settled(static_cast<size_t>(n), 0);
  std::priority_queue<Candidate, std::vector<Candidate>, std::greater<Candidate>> open;
  for (int i = 0; i < n; ++i) {
    if (!visible_with_clearance(obs, start, g.node[i], c_start)) continue;
    dist[i] = norm(g.node[i] - start);
    open.push({dist[i], i});
  }
  double best = kInf;
  int last = -1;
  while (!open.empty()) {
    const Candidate c = open.top();
    open.pop();
    if (settled[c.node] || c.distance > dist[c.node]) continue;
    if (c.distance >= best) break;  // no route through a farther node can be shorter
    settled[c.node] = 1;
    const Vec2 p = g.node[c.node];
    const double to_goal = norm(goal - p);
    if (c.distance + to_goal < best && visible_with_clearance(obs, p, goal, c_goal)) {
      best = c.distance + to_goal;
      last = c.node;
    }
    for (int k = g.first[c.node]; k < g.first[c.node + 1]; ++k) {
      const int j = g.neighbour[k];
      const double dj = c.distance + g.length[k];
      if (dj < dist[j]) {
        dist[j] = dj;
        prev[j] = c.node;
        open.push({dj, j});
      }
    }
  }
  if (last < 0) return false;
  for (int i = last; i >= 0; i = prev[i]) points.push_back(g.node[i]);
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

bool visible_with_clearance(const ObstacleView& obstacles, Vec2 a, Vec2 b, double c) {
  return !swept_disc_hits_obstacles(obstacles, a, b, std::max(c, kMinClearance));
}

double obstacle_clearance(const ObstacleView& obstacles, Vec2 p) {
  if (obstacles.count == 0) return kInf;
  return std::max(swept_obstacle_clearance(obstacles, p, p, 0.0), 0.0);
}

RouteGraph build_route_graph(const ObstacleView& obstacles, double inflation) {
  RouteGraph g;
  g.inflation = inflation;
  std::vector<Vec2> candidates;
  for (int i = 0; i < obstacles.count; ++i) corner_nodes(obstacles, i, inflation, candidates);
  for (const Vec2& c : candidates)
    if (obstacle_clearance(obstacles, c) >= inflation) g.node.push_back(c);
  const int n = static_cast<int>(g.node.size());
  std::vector<std::vector<std::pair<int, double>>> adjacent(static_cast<size_t>(n));
  const double c = inflation * (1.0 - 1e-9);
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j)
      if (visible_with_clearance(obstacles, g.node[i], g.node[j], c)) {
        const double len = norm(g.node[j] - g.node[i]);
        adjacent[i].emplace_back(j, len);
        adjacent[j].emplace_back(i, len);
      }
  g.first.assign(static_cast<size_t>(n) + 1, 0);
  for (int i = 0; i < n; ++i) {
    g.first[i + 1] = g.first[i] + static_cast<int32_t>(adjacent[i].size());
    for (const auto& [j, len] : adjacent[i]) {
      g.neighbour.push_back(j);
      g.length.push_back(len);
    }
  }
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
  if (clearance > 0.0 && !(out.found && out.point.size() == 1)) {  // a goal in sight is the route
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
  std::shared_ptr<const RouteGraph> held;
  auto graph = [&](double d) -> const RouteGraph& {
    held = cached_route_graph(obstacles, d);
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

}  // namespace

void plan_route_around(const ObstacleView& walls, const Vec2* centres, const double* radii, int n, Vec2 start,
                       Vec2 goal, double radius, double clearance, Route& out) {
  if (n == 0) {
    plan_route(walls, start, goal, radius, clearance, out);
    return;
  }
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
  const PreparedObstacles map =
      prepare_obstacles(vertices.data(), offsets.data(), static_cast<int>(offsets.size()) - 1);
  const ObstacleView view = map.view();
  RouteGraph held;
  auto graph = [&](double d) -> const RouteGraph& {
    held = build_route_graph(view, d);
    return held;
  };
  plan_with_tiers(view, graph, start, goal, radius, clearance, out);
  if (!out.found) plan_route(walls, start, goal, radius, clearance, out);
}

double route_length(const ObstacleView& obstacles, Vec2 start, Vec2 goal, double radius, double clearance) {
  if (obstacles.count == 0) return norm(goal - start);
  Route r;
  plan_route(obstacles, start, goal, radius, clearance, r);
  if (!r.found) return kInf;
  return norm(r.point[0] - start) + r.remaining[0];
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
  std::priority_queue<Candidate, std::vector<Candidate>, std::greater<Candidate>> open;
  for (int i = 0; i < m; ++i)
    if (visible_with_clearance(obstacles, g.node[i], goal, c_goal)) {
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
    if (visible_with_clearance(obstacles, p, goal, std::min(c_point, c_goal))) {
      out[k] = norm(goal - p);
      continue;
    }
    double best = kInf;
    for (int i = 0; i < m; ++i) {
      const double via = norm(g.node[i] - p) + to_goal[i];
      if (via < best && visible_with_clearance(obstacles, p, g.node[i], c_point)) best = via;
    }
    out[k] = best;
  }
}

void RouteFollower::plan(const ObstacleView& obstacles, Vec2 start, Vec2 goal, double radius, double clearance) {
  plan_route(obstacles, start, goal, radius, clearance, route);
  index = 0;
  replans = 0;
  yields = 0;
  best_remaining = kInf;
  stalled = 0.0;
  yielding = 0.0;
  last_step = -1;
}

Vec2 RouteFollower::target(const ObstacleView& obstacles, Vec2 position, Vec2 goal, double radius, double clearance,
                           int step, double dt, int agent) {
  const Vec2 ahead = route_target(obstacles, position, goal, radius, clearance);
  if (!route.found) return ahead;
  const double remaining = norm(route.point[index] - position) + route.remaining[index];
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
  const Vec2 away = position - route.point[index];
  const double len = norm(away);
  return len > 1e-9 ? position + (1.0 / len) * away : ahead;
}

Vec2 RouteFollower::route_target(const ObstacleView& obstacles, Vec2 position, Vec2 goal, double radius,
                                 double clearance) {
  if (!route.found) return goal;
  const int n = static_cast<int>(route.point.size());
  const double own = obstacle_clearance(obstacles, position);
  // Advance to the farthest point seen with half the planned clearance, or with the agent's own where a
  // neighbour pressed it closer to a wall than that.
  const double c_advance = std::min(0.5 * (radius + route.inflation), 0.99 * own);
  bool advanced = false;
  while (index + 1 < n && visible_with_clearance(obstacles, position, route.point[index + 1], c_advance)) {
    ++index;
    advanced = true;
  }
  // Pushed off the route (the point it heads for, the goal included, is behind a wall or closer to one than
  // the agent's radius on the way): re-plan from here.
  if (!advanced && !visible_with_clearance(obstacles, position, route.point[index], 0.99 * std::min(radius, own))) {
    const int replanned = replans + 1;
    plan(obstacles, position, goal, radius, clearance);
    replans = replanned;
    if (!route.found) return goal;
  }
  if (index + 1 >= static_cast<int>(route.point.size())) return goal;
  const Vec2 w = route.point[index];
  const double to_point = norm(w - position);
  if (to_point < 1e-9) return route.point[index + 1];
  return position + ((to_point + route.remaining[index]) / to_point) * (w - position);
}

}  // namespace socialnav
