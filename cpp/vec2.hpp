// Minimal 2-D vector algebra for the native core (double precision throughout).
#pragma once

#include <cmath>

namespace socialnav {

struct Vec2 {
  double x = 0.0;
  double y = 0.0;
};

inline Vec2 operator+(Vec2 a, Vec2 b) { return {a.x + b.x, a.y + b.y}; }
inline Vec2 operator-(Vec2 a, Vec2 b) { return {a.x - b.x, a.y - b.y}; }
inline Vec2 operator-(Vec2 a) { return {-a.x, -a.y}; }
inline Vec2 operator*(double s, Vec2 a) { return {s * a.x, s * a.y}; }
inline Vec2 operator*(Vec2 a, double s) { return {s * a.x, s * a.y}; }
inline Vec2 operator/(Vec2 a, double s) { return {a.x / s, a.y / s}; }
inline double dot(Vec2 a, Vec2 b) { return a.x * b.x + a.y * b.y; }
// z-component of the 3-D cross product: > 0 when b is counter-clockwise of a.
inline double det(Vec2 a, Vec2 b) { return a.x * b.y - a.y * b.x; }
inline double abs_sq(Vec2 a) { return dot(a, a); }
inline double norm(Vec2 a) { return std::sqrt(abs_sq(a)); }
inline Vec2 normalize(Vec2 a) { return a / norm(a); }

// Straight to the goal at `speed`, shortening the last step so as never to pass the goal
// (linear pedestrians and the linear robot policy).
inline Vec2 straight_to_goal_velocity(Vec2 position, Vec2 goal, double speed, double dt) {
  const Vec2 to_goal = goal - position;
  const double d = norm(to_goal);
  const double s = d / dt < speed ? d / dt : speed;
  return d > 1e-12 ? (s / d) * to_goal : Vec2{};
}

}  // namespace socialnav
