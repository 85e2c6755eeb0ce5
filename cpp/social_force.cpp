#include "social_force.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace socialnav {

Vec2 social_force_repulsion(Vec2 r, Vec2 v_b, const SocialForceParams& params) {
  const double r1 = norm(r);
  if (r1 < 1e-9) return Vec2{};  // coincident centres: no defined direction
  const double speed_b = norm(v_b);
  const Vec2 step = params.step_time * v_b;  // s * e_b
  const double s = params.step_time * speed_b;
  const Vec2 r_minus = r - step;
  const double r2 = norm(r_minus);
  const double sum = r1 + r2;
  const double b = 0.5 * std::sqrt(std::max(sum * sum - s * s, 0.0));
  if (b < 1e-9 || r2 < 1e-9) {
    // Degenerate ellipse (the other walks straight at us): fall back to the circular potential.
    const double magnitude = params.v0 / params.sigma * std::exp(-r1 / params.sigma);
    return (magnitude / r1) * r;
  }
  // f = -grad_r V(b(r)), with db/dr = (r1 + r2) / (4 b) * (r/r1 + (r - s e_b)/r2).
  const double dv_db = params.v0 / params.sigma * std::exp(-b / params.sigma);
  const double scale = dv_db * sum / (4.0 * b);
  return scale * (r / r1 + r_minus / r2);
}

Vec2 social_force_wall_repulsion(Vec2 position, const ObstacleView& obstacles, const SocialForceParams& params) {
  Vec2 force{};
  double best_sq = std::numeric_limits<double>::infinity();
  Vec2 best_point{};
  bool parity = false;
  for (int i = 0; i < obstacles.count; ++i) {
    const ObstacleVertex& v = obstacles.vertex[i];
    const Vec2 a = v.point, b = obstacles.vertex[v.next].point;
    if (v.own_edge) {
      const Vec2 c = closest_point_segment(a, b, position);
      const double d_sq = abs_sq(position - c);
      if (d_sq < best_sq) {
        best_sq = d_sq;
        best_point = c;
      }
    }
    if (v.solid && (a.y > position.y) != (b.y > position.y) &&
        position.x < a.x + (position.y - a.y) * (b.x - a.x) / (b.y - a.y))
      parity = !parity;
    if (v.next > i) continue;
    // The polygon's last vertex: its force, from the closest point over its edges.
    const double d = std::sqrt(best_sq);
    if (d > 1e-12) {
      const double magnitude = params.wall_u0 / params.wall_r * std::exp(-(parity ? 0.0 : d) / params.wall_r);
      const Vec2 away = (position - best_point) / d;
      force = force + (parity ? -magnitude : magnitude) * away;
    }
    best_sq = std::numeric_limits<double>::infinity();
    parity = false;
  }
  return force;
}

Vec2 social_force_new_velocity(const SocialForceAgent& self, const SocialForceOther* others, int n,
                               const SocialForceParams& params, double dt, const ObstacleView& obstacles) {
  Vec2 force = (self.desired_velocity - self.velocity) / params.relaxation_time;
  const double desired_speed = norm(self.desired_velocity);
  const Vec2 e = desired_speed > 1e-9 ? self.desired_velocity / desired_speed : Vec2{};
  const double cos_phi = std::cos(params.fov_half_angle);
  for (int k = 0; k < n; ++k) {
    const Vec2 f = social_force_repulsion(self.position - others[k].position, others[k].velocity, params);
    // The other is perceived in front when the force it exerts points against our heading.
    const double f_norm = norm(f);
    const double weight = dot(e, -f) >= f_norm * cos_phi ? 1.0 : params.outside_fov_weight;
    force = force + weight * f;
  }
  if (obstacles.count > 0) force = force + social_force_wall_repulsion(self.position, obstacles, params);
  Vec2 v = self.velocity + dt * force;
  const double speed = norm(v);
  if (speed > self.max_speed && speed > 0.0) v = (self.max_speed / speed) * v;
  return v;
}

}  // namespace socialnav
