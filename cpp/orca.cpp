#include "orca.hpp"

#include <algorithm>

namespace socialnav {

void OrcaScratch::offer(int candidate, double candidate_dist_sq, int max_neighbors) {
  if (!(candidate_dist_sq < range_sq)) return;
  int i = count;
  if (count < max_neighbors) ++count;
  else i = count - 1;  // overwrite the farthest
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
bool linear_program1(const Line* lines, int line_no, double radius, Vec2 opt_velocity,
                     bool direction_opt, Vec2& result) {
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
    if (denominator >= 0.0) t_right = std::min(t_right, t);
    else t_left = std::max(t_left, t);
    if (t_left > t_right) return false;
  }

  if (direction_opt) {
    result = dot(opt_velocity, line.direction) > 0.0 ? line.point + t_right * line.direction
                                                     : line.point + t_left * line.direction;
  } else {
    const double t = dot(line.direction, opt_velocity - line.point);
    if (t < t_left) result = line.point + t_left * line.direction;
    else if (t > t_right) result = line.point + t_right * line.direction;
    else result = line.point + t * line.direction;
  }
  return true;
}

// Incremental 2-D linear program (randomisation is unnecessary for ~10 constraints).
// Returns the number of lines satisfied in order; < n means infeasible at that line.
int linear_program2(const Line* lines, int n, double radius, Vec2 opt_velocity,
                    bool direction_opt, Vec2& result) {
  if (direction_opt) result = opt_velocity * radius;  // opt_velocity is a unit direction here
  else if (abs_sq(opt_velocity) > radius * radius) result = normalize(opt_velocity) * radius;
  else result = opt_velocity;

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
// sweeping the lines from `begin_line` and solving a 2-D program on their bisectors.
void linear_program3(const Line* lines, int n, int begin_line, double radius, Vec2& result,
                     Line* projected) {
  double distance = 0.0;
  for (int i = begin_line; i < n; ++i) {
    if (det(lines[i].direction, lines[i].point - result) <= distance) continue;
    int m = 0;
    for (int j = 0; j < i; ++j) {
      Line line;
      const double determinant = det(lines[i].direction, lines[j].direction);
      if (std::fabs(determinant) <= kOrcaEpsilon) {
        if (dot(lines[i].direction, lines[j].direction) > 0.0) continue;  // same direction
        line.point = 0.5 * (lines[i].point + lines[j].point);           // opposite
      } else {
        line.point = lines[i].point +
                     (det(lines[j].direction, lines[i].point - lines[j].point) / determinant) *
                         lines[i].direction;
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

}  // namespace

Vec2 orca_new_velocity(const OrcaAgent& self, const OrcaNeighbor* neighbors, int n,
                       double time_horizon, double time_step, OrcaScratch& scratch) {
  Line* lines = scratch.lines;
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
  const int line_fail = linear_program2(lines, n, self.max_speed, self.pref_velocity, false, result);
  if (line_fail < n) linear_program3(lines, n, line_fail, self.max_speed, result, scratch.projected);
  return result;
}

Vec2 orca_new_velocity_select(const OrcaAgent& self, const OrcaNeighbor* candidates, int n,
                              const OrcaParams& params, double time_step, OrcaScratch& scratch) {
  scratch.begin(params.neighbor_dist);
  for (int j = 0; j < n; ++j)
    scratch.offer(j, abs_sq(candidates[j].position - self.position), params.max_neighbors);
  OrcaNeighbor selected[kMaxOrcaNeighbors];
  for (int k = 0; k < scratch.count; ++k) selected[k] = candidates[scratch.index[k]];
  return orca_new_velocity(self, selected, scratch.count, params.time_horizon, time_step, scratch);
}

}  // namespace socialnav
