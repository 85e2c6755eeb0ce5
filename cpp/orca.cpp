#include "orca.hpp"

#include <algorithm>
#include <limits>

#include "multiversion.hpp"

namespace socialnav {

void OrcaScratch::offer(int candidate, double candidate_dist_sq, int max_neighbors) {
  if (!(candidate_dist_sq < range_sq)) return;
  int i = count;
  if (count < max_neighbors)
    ++count;
  else
    i = count - 1;  // overwrite the farthest
  while (i != 0 && candidate_dist_sq < dist_sq[i - 1]) {
    dist_sq[i] = dist_sq[i - 1];
    index[i] = index[i - 1];
    --i;
  }
  dist_sq[i] = candidate_dist_sq;
  index[i] = candidate;
  if (count == max_neighbors) range_sq = dist_sq[count - 1];
}

namespace {

// Best point on line `line_no` that satisfies lines [0, line_no) and the speed disc.
// Returns false when that segment is empty.
bool linear_program1(const Line* lines, int line_no, double radius, Vec2 opt_velocity, bool direction_opt,
                     Vec2& result) {
  const Line& line = lines[line_no];
  const double dot_product = dot(line.point, line.direction);
  const double discriminant = dot_product * dot_product + radius * radius - abs_sq(line.point);
  if (discriminant < 0.0) return false;  // the line misses the speed disc

  const double sqrt_discriminant = std::sqrt(discriminant);
  double t_left = -dot_product - sqrt_discriminant;
  double t_right = -dot_product + sqrt_discriminant;

  for (int i = 0; i < line_no; ++i) {
    const double denominator = det(line.direction, lines[i].direction);
    const double numerator = det(lines[i].direction, line.point - lines[i].point);
    if (std::fabs(denominator) <= kOrcaEpsilon) {
      // Parallel: either line i excludes all of this line or none of it.
      if (numerator < 0.0) return false;
      continue;
    }
    const double t = numerator / denominator;
    if (denominator >= 0.0)
      t_right = std::min(t_right, t);
    else
      t_left = std::max(t_left, t);
    if (t_left > t_right) return false;
  }

  if (direction_opt) {
    result = dot(opt_velocity, line.direction) > 0.0 ? line.point + t_right * line.direction
                                                     : line.point + t_left * line.direction;
  } else {
    const double t = dot(line.direction, opt_velocity - line.point);
    if (t < t_left)
      result = line.point + t_left * line.direction;
    else if (t > t_right)
      result = line.point + t_right * line.direction;
    else
      result = line.point + t * line.direction;
  }
  return true;
}

// Incremental 2-D linear program (randomisation is unnecessary for ~10 constraints).
// Returns the number of lines satisfied in order; < n means infeasible at that line.
int linear_program2(const Line* lines, int n, double radius, Vec2 opt_velocity, bool direction_opt, Vec2& result) {
  if (direction_opt)
    result = opt_velocity * radius;  // opt_velocity is a unit direction here
  else if (abs_sq(opt_velocity) > radius * radius)
    result = normalize(opt_velocity) * radius;
  else
    result = opt_velocity;

  for (int i = 0; i < n; ++i) {
    if (det(lines[i].direction, lines[i].point - result) > 0.0) {
      const Vec2 previous = result;
      if (!linear_program1(lines, i, radius, opt_velocity, direction_opt, result)) {
        result = previous;
        return i;
      }
    }
  }
  return n;
}

// Infeasible case: minimise the maximum signed distance into the violated half-planes by
// sweeping the lines from `begin_line` and solving a 2-D program on their bisectors. The first
// `n_hard` lines (static obstacles) are never relaxed: they enter every sub-problem unchanged.
void linear_program3(const Line* lines, int n, int n_hard, int begin_line, double radius, Vec2& result,
                     Line* projected) {
  double distance = 0.0;
  for (int i = begin_line; i < n; ++i) {
    if (det(lines[i].direction, lines[i].point - result) <= distance) continue;
    int m = 0;
    for (int j = 0; j < n_hard; ++j) projected[m++] = lines[j];
    for (int j = n_hard; j < i; ++j) {
      Line line;
      const double determinant = det(lines[i].direction, lines[j].direction);
      if (std::fabs(determinant) <= kOrcaEpsilon) {
        if (dot(lines[i].direction, lines[j].direction) > 0.0) continue;  // same direction
        line.point = 0.5 * (lines[i].point + lines[j].point);             // opposite
      } else {
        line.point = lines[i].point +
                     (det(lines[j].direction, lines[i].point - lines[j].point) / determinant) * lines[i].direction;
      }
      line.direction = normalize(lines[j].direction - lines[i].direction);
      projected[m++] = line;
    }
    const Vec2 previous = result;
    const Vec2 outward{-lines[i].direction.y, lines[i].direction.x};
    if (linear_program2(projected, m, radius, outward, true, result) < m) {
      // Only floating-point error can make this fail; keep the previous optimum.
      result = previous;
    }
    distance = det(lines[i].direction, lines[i].point - result);
  }
}

// Left and right leg directions of the cone from the agent tangent to a disc of `radius` around
// relative position `p` (|p| > radius). One division per vertex (a multiplication by its inverse
// after), where RVO2 divides each component: the results differ by an ulp at most.
struct Legs {
  Vec2 left, right;
};
inline Legs legs(Vec2 p, double dist_sq, double radius) {
  const double leg = std::sqrt(dist_sq - radius * radius);
  const double inv = 1.0 / dist_sq;
  return Legs{Vec2{(p.x * leg - p.y * radius) * inv, (p.x * radius + p.y * leg) * inv},
              Vec2{(p.x * leg + p.y * radius) * inv, (-p.x * radius + p.y * leg) * inv}};
}
inline Vec2 left_leg(Vec2 p, double dist_sq, double radius) {
  const double leg = std::sqrt(dist_sq - radius * radius);
  const double inv = 1.0 / dist_sq;
  return Vec2{(p.x * leg - p.y * radius) * inv, (p.x * radius + p.y * leg) * inv};
}
inline Vec2 right_leg(Vec2 p, double dist_sq, double radius) {
  const double leg = std::sqrt(dist_sq - radius * radius);
  const double inv = 1.0 / dist_sq;
  return Vec2{(p.x * leg + p.y * radius) * inv, (-p.x * radius + p.y * leg) * inv};
}

// RVO2's obstacle neighbours: vertices whose edge faces the agent (agent strictly on its right,
// the outside of a counter-clockwise polygon) within range, sorted by distance to the edge (ties in
// RVO2's tree-query order where the view has the tree, else in vertex order).
// Also compiled for AVX2, chosen at load time where the CPU has it: the query's vectorised pass then
// takes 4 edges at a time instead of 2 (6 % of a walled world's ORCA time on the benchmark map). The
// same IEEE operations in the same order (no contraction into FMA: -ffp-contract=off), so the
// same values on either path.
SOCIALNAV_AVX2_CLONE void select_obstacles(const OrcaAgent& self, const ObstacleView& obstacles, double range_sq,
                                           OrcaScratch& scratch) {
  const int n = obstacles.count;
  if (static_cast<int>(scratch.obstacle_key.size()) < n) {
    scratch.obstacle_key.resize(n);
    scratch.obstacle_index.resize(n);
    scratch.obstacle_dist_sq.resize(n);
  }
  double* __restrict key = scratch.obstacle_key.data();
  const double* __restrict px = obstacles.orca_edges;
  const double* __restrict py = px + n;
  const double* __restrict ex = px + 2 * n;
  const double* __restrict ey = px + 3 * n;
  const double* __restrict len_sq = px + 4 * n;
  const double* __restrict qx = px + 5 * n;
  const double* __restrict qy = px + 6 * n;
  const double ax = self.position.x, ay = self.position.y;
  constexpr double kInf = std::numeric_limits<double>::infinity();
  // Branch-free over all edges (the compiler vectorises it): the squared distance of each edge that
  // faces the agent within range, +inf for the others. The arithmetic is RVO2's, operation for
  // operation (its leftOf and distSqPointLineSegment): an agent's distances to two edges meeting at
  // its nearest vertex are then equal to the bit, and their order is the tree query's.
  for (int i = 0; i < n; ++i) {
    const double tx = ax - px[i], ty = ay - py[i];
    const double left = ex[i] * ty - ey[i] * tx;  // RVO2's leftOf(p1, p2, agent)
    const double r = (tx * ex[i] + ty * ey[i]) / len_sq[i];
    // Beyond an end, the distance to that end point itself; else to the point at r along the edge.
    const double cx = r < 0.0 ? px[i] : (r > 1.0 ? qx[i] : px[i] + r * ex[i]);
    const double cy = r < 0.0 ? py[i] : (r > 1.0 ? qy[i] : py[i] + r * ey[i]);
    const double dx = ax - cx, dy = ay - cy;
    const double dist_sq = dx * dx + dy * dy;
    // Facing (strictly on the edge's right), line and segment within range; written without
    // branches so that the loop vectorises.
    const double line_dist_sq = left * left / len_sq[i];
    const double facing = left < 0.0 ? dist_sq : kInf;
    const double in_range = line_dist_sq < range_sq ? facing : kInf;
    key[i] = dist_sq < range_sq ? in_range : kInf;
  }
  // The selected ones, compacted without branches (in vertex order), then insertion-sorted by
  // distance (a strict comparison: ties keep vertex order, as RVO2's insertion does).
  int* __restrict idx = scratch.obstacle_index.data();
  double* __restrict dsq = scratch.obstacle_dist_sq.data();
  int m = 0;
  for (int i = 0; i < n; ++i) {
    idx[m] = i;
    dsq[m] = key[i];
    m += key[i] < kInf;
  }
  // With RVO2's tree (an ORCA view), equally distant edges (two edges meeting at the vertex closest to
  // the agent, the common case) keep the order RVO2's tree query inserts them in.
  const bool tree = obstacles.tree_parent != nullptr;
  for (int j = 1; j < m; ++j) {
    const int i = idx[j];
    const double dist_sq = dsq[j];
    int k = j;
    while (k != 0 && (dist_sq < dsq[k - 1] || (tree && dist_sq == dsq[k - 1] &&
                                               tree_query_precedes(obstacles, i, idx[k - 1], self.position)))) {
      idx[k] = idx[k - 1];
      dsq[k] = dsq[k - 1];
      --k;
    }
    idx[k] = i;
    dsq[k] = dist_sq;
  }
  scratch.obstacle_count = m;
}

// One ORCA half-plane per selected obstacle edge (van den Berg et al. 2011, Sec. 5; RVO2's cases):
// edges already excluded by earlier lines are skipped; an agent already touching a vertex or an
// edge gets a line through the origin that forbids moving further in; otherwise the velocity
// obstacle is the edge's cut-off segment (scaled by 1/tau_obst) with its two legs, where a leg
// at a non-convex vertex continues the edge and a leg that would point into the neighbouring edge
// is replaced by that edge ("foreign" leg, which adds no line when it is the closest part).
// Returns the number of lines written.
int obstacle_lines(const OrcaAgent& self, const ObstacleView& obstacles, double time_horizon_obst,
                   const OrcaScratch& scratch, Line* lines) {
  const double inv_time_horizon_obst = 1.0 / time_horizon_obst;
  const double radius = self.radius;
  const double radius_sq = radius * radius;
  int count = 0;
  for (int selected = 0; selected < scratch.obstacle_count; ++selected) {
    const int first = scratch.obstacle_index[selected];
    const ObstacleVertex* obstacle1 = &obstacles.vertex[first];
    const ObstacleVertex* obstacle2 = &obstacles.vertex[obstacle1->next];
    const Vec2 relative_position1 = obstacle1->point - self.position;
    const Vec2 relative_position2 = obstacle2->point - self.position;

    // Already excluded by a previous obstacle line: both cut-off ends are on the far side of it.
    bool already_covered = false;
    for (int j = 0; j < count; ++j) {
      if (det(inv_time_horizon_obst * relative_position1 - lines[j].point, lines[j].direction) -
                  inv_time_horizon_obst * radius >=
              -kOrcaEpsilon &&
          det(inv_time_horizon_obst * relative_position2 - lines[j].point, lines[j].direction) -
                  inv_time_horizon_obst * radius >=
              -kOrcaEpsilon) {
        already_covered = true;
        break;
      }
    }
    if (already_covered) continue;

    const double dist_sq1 = abs_sq(relative_position1);
    const double dist_sq2 = abs_sq(relative_position2);
    const Vec2 obstacle_vector = obstacle1->edge;
    const double s = dot(-relative_position1, obstacle_vector) / abs_sq(obstacle_vector);
    const double dist_sq_line = abs_sq(-relative_position1 - s * obstacle_vector);

    Line line;
    if (s < 0.0 && dist_sq1 <= radius_sq) {
      // Touching the left vertex (ignored when non-convex: the neighbouring edge handles it).
      if (obstacle1->convex) {
        line.point = Vec2{};
        line.direction = normalize(Vec2{-relative_position1.y, relative_position1.x});
        lines[count++] = line;
      }
      continue;
    }
    if (s > 1.0 && dist_sq2 <= radius_sq) {
      // Touching the right vertex: only when convex and not left to the next edge.
      if (obstacle2->convex && det(relative_position2, obstacle2->unit_dir) >= 0.0) {
        line.point = Vec2{};
        line.direction = normalize(Vec2{-relative_position2.y, relative_position2.x});
        lines[count++] = line;
      }
      continue;
    }
    if (s >= 0.0 && s < 1.0 && dist_sq_line <= radius_sq) {
      // Touching the edge itself.
      line.point = Vec2{};
      line.direction = -obstacle1->unit_dir;
      lines[count++] = line;
      continue;
    }

    // No contact: the legs of the velocity obstacle.
    Vec2 left_leg_direction, right_leg_direction;
    if (s < 0.0 && dist_sq_line <= radius_sq) {
      // Seen obliquely: the left vertex alone defines the velocity obstacle.
      if (!obstacle1->convex) continue;
      obstacle2 = obstacle1;
      const Legs both = legs(relative_position1, dist_sq1, radius);
      left_leg_direction = both.left;
      right_leg_direction = both.right;
    } else if (s > 1.0 && dist_sq_line <= radius_sq) {
      // Seen obliquely: the right vertex alone defines it.
      if (!obstacle2->convex) continue;
      obstacle1 = obstacle2;
      const Legs both = legs(relative_position2, dist_sq2, radius);
      left_leg_direction = both.left;
      right_leg_direction = both.right;
    } else {
      left_leg_direction = obstacle1->convex ? left_leg(relative_position1, dist_sq1, radius)
                                             : -obstacle1->unit_dir;  // continues the cut-off line
      right_leg_direction = obstacle2->convex ? right_leg(relative_position2, dist_sq2, radius) : obstacle1->unit_dir;
    }

    // A leg pointing into the neighbouring edge is replaced by that edge's direction.
    const ObstacleVertex& left_neighbor = obstacles.vertex[obstacle1->prev];
    bool is_left_leg_foreign = false, is_right_leg_foreign = false;
    if (obstacle1->convex && det(left_leg_direction, -left_neighbor.unit_dir) >= 0.0) {
      left_leg_direction = -left_neighbor.unit_dir;
      is_left_leg_foreign = true;
    }
    if (obstacle2->convex && det(right_leg_direction, obstacle2->unit_dir) <= 0.0) {
      right_leg_direction = obstacle2->unit_dir;
      is_right_leg_foreign = true;
    }

    // Cut-off centres and the projection of the current velocity on the velocity obstacle.
    const Vec2 left_cutoff = inv_time_horizon_obst * (obstacle1->point - self.position);
    const Vec2 right_cutoff = inv_time_horizon_obst * (obstacle2->point - self.position);
    const Vec2 cutoff_vector = right_cutoff - left_cutoff;
    const bool single_vertex = obstacle1 == obstacle2;
    const double t = single_vertex ? 0.5 : dot(self.velocity - left_cutoff, cutoff_vector) / abs_sq(cutoff_vector);
    const double t_left = dot(self.velocity - left_cutoff, left_leg_direction);
    const double t_right = dot(self.velocity - right_cutoff, right_leg_direction);

    if ((t < 0.0 && t_left < 0.0) || (single_vertex && t_left < 0.0 && t_right < 0.0)) {
      // Closest to the left cut-off circle.
      const Vec2 unit_w = normalize(self.velocity - left_cutoff);
      line.direction = Vec2{unit_w.y, -unit_w.x};
      line.point = left_cutoff + radius * inv_time_horizon_obst * unit_w;
      lines[count++] = line;
      continue;
    }
    if (t > 1.0 && t_right < 0.0) {
      // Closest to the right cut-off circle.
      const Vec2 unit_w = normalize(self.velocity - right_cutoff);
      line.direction = Vec2{unit_w.y, -unit_w.x};
      line.point = right_cutoff + radius * inv_time_horizon_obst * unit_w;
      lines[count++] = line;
      continue;
    }

    // Otherwise the closest of the cut-off segment, the left leg and the right leg.
    constexpr double kInf = std::numeric_limits<double>::infinity();
    const double dist_sq_cutoff =
        (t < 0.0 || t > 1.0 || single_vertex) ? kInf : abs_sq(self.velocity - (left_cutoff + t * cutoff_vector));
    const double dist_sq_left =
        t_left < 0.0 ? kInf : abs_sq(self.velocity - (left_cutoff + t_left * left_leg_direction));
    const double dist_sq_right =
        t_right < 0.0 ? kInf : abs_sq(self.velocity - (right_cutoff + t_right * right_leg_direction));

    if (dist_sq_cutoff <= dist_sq_left && dist_sq_cutoff <= dist_sq_right) {
      line.direction = -obstacle1->unit_dir;
      line.point = left_cutoff + radius * inv_time_horizon_obst * Vec2{-line.direction.y, line.direction.x};
      lines[count++] = line;
    } else if (dist_sq_left <= dist_sq_right) {
      if (is_left_leg_foreign) continue;
      line.direction = left_leg_direction;
      line.point = left_cutoff + radius * inv_time_horizon_obst * Vec2{-line.direction.y, line.direction.x};
      lines[count++] = line;
    } else {
      if (is_right_leg_foreign) continue;
      line.direction = -right_leg_direction;
      line.point = right_cutoff + radius * inv_time_horizon_obst * Vec2{-line.direction.y, line.direction.x};
      lines[count++] = line;
    }
  }
  return count;
}

}  // namespace

Vec2 orca_new_velocity(const OrcaAgent& self, const OrcaNeighbor* neighbors, int n, double time_horizon,
                       double time_step, OrcaScratch& scratch) {
  return orca_new_velocity(self, ObstacleView{}, 1.0, neighbors, n, time_horizon, time_step, scratch);
}

Vec2 orca_new_velocity(const OrcaAgent& self, const ObstacleView& obstacles, double time_horizon_obst,
                       const OrcaNeighbor* neighbors, int n, double time_horizon, double time_step,
                       OrcaScratch& scratch) {
  int n_obstacle_lines = 0;
  if (obstacles.count > 0) {
    const double range = time_horizon_obst * self.max_speed + self.radius;
    select_obstacles(self, obstacles, range * range, scratch);
    scratch.reserve_lines(scratch.obstacle_count + n);
    n_obstacle_lines = obstacle_lines(self, obstacles, time_horizon_obst, scratch, scratch.lines.data());
  } else {
    scratch.reserve_lines(n);
  }
  Line* lines = scratch.lines.data() + n_obstacle_lines;
  const double inv_time_horizon = 1.0 / time_horizon;
  for (int k = 0; k < n; ++k) {
    const OrcaNeighbor& other = neighbors[k];
    const Vec2 relative_position = other.position - self.position;
    const Vec2 relative_velocity = self.velocity - other.velocity;
    const double dist_sq = abs_sq(relative_position);
    const double combined_radius = self.radius + other.radius;
    const double combined_radius_sq = combined_radius * combined_radius;

    Line line;
    Vec2 u;
    if (dist_sq > combined_radius_sq) {
      // No collision yet: velocity obstacle truncated at the time horizon.
      const Vec2 w = relative_velocity - inv_time_horizon * relative_position;
      const double w_length_sq = abs_sq(w);
      const double dot_product1 = dot(w, relative_position);
      if (dot_product1 < 0.0 && dot_product1 * dot_product1 > combined_radius_sq * w_length_sq) {
        // Closest boundary point lies on the cut-off circle.
        const double w_length = std::sqrt(w_length_sq);
        const Vec2 unit_w = w / w_length;
        line.direction = Vec2{unit_w.y, -unit_w.x};
        u = (combined_radius * inv_time_horizon - w_length) * unit_w;
      } else {
        // Closest boundary point lies on one of the two legs of the cone.
        const double leg = std::sqrt(dist_sq - combined_radius_sq);
        if (det(relative_position, w) > 0.0) {
          line.direction = Vec2{relative_position.x * leg - relative_position.y * combined_radius,
                                relative_position.x * combined_radius + relative_position.y * leg} /
                           dist_sq;
        } else {
          line.direction = -Vec2{relative_position.x * leg + relative_position.y * combined_radius,
                                 -relative_position.x * combined_radius + relative_position.y * leg} /
                           dist_sq;
        }
        const double dot_product2 = dot(relative_velocity, line.direction);
        u = dot_product2 * line.direction - relative_velocity;
      }
    } else {
      // Already overlapping: resolve within one time step.
      const double inv_time_step = 1.0 / time_step;
      const Vec2 w = relative_velocity - inv_time_step * relative_position;
      const double w_length = norm(w);
      const Vec2 unit_w = w / w_length;
      line.direction = Vec2{unit_w.y, -unit_w.x};
      u = (combined_radius * inv_time_step - w_length) * unit_w;
    }
    // Reciprocity: each agent takes half of the required change.
    line.point = self.velocity + 0.5 * u;
    lines[k] = line;
  }

  Vec2 result;
  const Line* all_lines = scratch.lines.data();
  const int total = n_obstacle_lines + n;
  const int line_fail = linear_program2(all_lines, total, self.max_speed, self.pref_velocity, false, result);
  if (line_fail < total)
    linear_program3(all_lines, total, n_obstacle_lines, line_fail, self.max_speed, result, scratch.projected.data());
  return result;
}

int orca_obstacle_lines(const OrcaAgent& self, const ObstacleView& obstacles, double time_horizon_obst,
                        OrcaScratch& scratch) {
  const double range = time_horizon_obst * self.max_speed + self.radius;
  select_obstacles(self, obstacles, range * range, scratch);
  scratch.reserve_lines(scratch.obstacle_count);
  return obstacle_lines(self, obstacles, time_horizon_obst, scratch, scratch.lines.data());
}

Vec2 orca_new_velocity_select(const OrcaAgent& self, const OrcaNeighbor* candidates, int n, const OrcaParams& params,
                              double time_step, OrcaScratch& scratch, const ObstacleView& obstacles) {
  scratch.begin(params.neighbor_dist);
  for (int j = 0; j < n; ++j) scratch.offer(j, abs_sq(candidates[j].position - self.position), params.max_neighbors);
  OrcaNeighbor selected[kMaxOrcaNeighbors];
  for (int k = 0; k < scratch.count; ++k) selected[k] = candidates[scratch.index[k]];
  return orca_new_velocity(self, obstacles, params.time_horizon_obst, selected, scratch.count, params.time_horizon,
                           time_step, scratch);
}

void orca_step_agents(int n, const double* p, const double* v, const double* pv, const double* r, const double* ms,
                      const OrcaParams& params, double time_step, const ObstacleView& obstacles, double* out) {
  OrcaScratch scratch;
  std::vector<OrcaNeighbor> selected(kMaxOrcaNeighbors);
  for (int i = 0; i < n; ++i) {
    const Vec2 pi{p[2 * i], p[2 * i + 1]};
    scratch.begin(params.neighbor_dist);
    for (int j = 0; j < n; ++j) {
      if (j == i) continue;
      scratch.offer(j, abs_sq(Vec2{p[2 * j], p[2 * j + 1]} - pi), params.max_neighbors);
    }
    for (int k = 0; k < scratch.count; ++k) {
      const int j = scratch.index[k];
      selected[k] = OrcaNeighbor{Vec2{p[2 * j], p[2 * j + 1]}, Vec2{v[2 * j], v[2 * j + 1]}, r[j]};
    }
    const OrcaAgent self{pi, Vec2{v[2 * i], v[2 * i + 1]}, r[i], ms[i], Vec2{pv[2 * i], pv[2 * i + 1]}};
    const Vec2 nv = orca_new_velocity(self, obstacles, params.time_horizon_obst, selected.data(), scratch.count,
                                      params.time_horizon, time_step, scratch);
    out[2 * i] = nv.x;
    out[2 * i + 1] = nv.y;
  }
}

}  // namespace socialnav
