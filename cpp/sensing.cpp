#include "sensing.hpp"

#include <algorithm>
#include <cmath>

namespace socialnav {

namespace {

constexpr uint64_t kGolden = 0x9E3779B97F4A7C15ULL;

// splitmix64's finaliser (Steele, Lea & Flood, OOPSLA 2014): a bijective mix of 64 bits.
inline uint64_t fmix(uint64_t z) {
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

inline uint64_t draw_bits(int64_t seed, int64_t step, int64_t index, uint64_t stream) {
  uint64_t h = fmix(static_cast<uint64_t>(seed) + kGolden);
  h = fmix((h ^ static_cast<uint64_t>(step)) + kGolden);
  h = fmix((h ^ static_cast<uint64_t>(index)) + kGolden);
  return fmix((h ^ stream) + kGolden);
}

inline double wrap_angle(double a) { return std::remainder(a, 2.0 * M_PI); }

// Distance from the origin `eye` to segment [p, q].
inline double segment_distance(Vec2 eye, Vec2 p, Vec2 q) {
  const Vec2 e = q - p;
  const double len_sq = abs_sq(e);
  double s = len_sq > 0.0 ? dot(eye - p, e) / len_sq : 0.0;
  s = std::clamp(s, 0.0, 1.0);
  return norm(p + s * e - eye);
}

// Whether the ray eye + t u, 0 < t < t_max, crosses a wall edge or an occluding disc.
bool ray_blocked(Vec2 eye, Vec2 u, double t_max, const ObstacleView& walls, const double* other_pos,
                 const double* other_radius, const uint8_t* skip, int n_others) {
  for (int k = 0; k < walls.count; ++k) {
    const ObstacleVertex& v = walls.vertex[k];
    if (!v.own_edge) continue;
    const double denom = det(u, v.edge);
    if (denom == 0.0) continue;  // parallel: at most a grazing touch
    const Vec2 w = v.point - eye;
    const double t = det(w, v.edge) / denom;
    const double s = det(w, u) / denom;
    if (t > 0.0 && t < t_max && s >= 0.0 && s <= 1.0) return true;
  }
  for (int k = 0; k < n_others; ++k) {
    if (skip && skip[k]) continue;
    const Vec2 c{other_pos[2 * k] - eye.x, other_pos[2 * k + 1] - eye.y};
    const double r = other_radius[k];
    const double b = dot(u, c);
    const double h_sq = abs_sq(c) - b * b;
    if (h_sq >= r * r) continue;
    const double half = std::sqrt(r * r - h_sq);
    if (b + half > 0.0 && b - half < t_max) return true;
  }
  return false;
}

// Angles (relative to `phi`) of where segment [p, q] crosses the circle (c, r), appended to `cuts`.
void segment_circle_cuts(Vec2 eye, double phi, Vec2 p, Vec2 q, Vec2 c, double r, std::vector<double>& cuts) {
  const Vec2 e = q - p;
  const Vec2 f = p - c;
  const double a = abs_sq(e);
  const double b = dot(f, e);
  const double disc = b * b - a * (abs_sq(f) - r * r);
  if (a == 0.0 || disc < 0.0) return;
  const double root = std::sqrt(disc);
  for (double s : {(-b - root) / a, (-b + root) / a}) {
    if (s < 0.0 || s > 1.0) continue;
    const Vec2 x = p + s * e - eye;
    cuts.push_back(wrap_angle(std::atan2(x.y, x.x) - phi));
  }
}

// Angles (relative to `phi`) of where the circles (c1, r1) and (c2, r2) cross, appended to `cuts`.
void circle_circle_cuts(Vec2 eye, double phi, Vec2 c1, double r1, Vec2 c2, double r2, std::vector<double>& cuts) {
  const Vec2 d = c2 - c1;
  const double dist = norm(d);
  if (dist == 0.0 || dist > r1 + r2 || dist < std::abs(r1 - r2)) return;
  const double a = (r1 * r1 - r2 * r2 + dist * dist) / (2.0 * dist);
  const double h = std::sqrt(std::max(0.0, r1 * r1 - a * a));
  const Vec2 mid = c1 + (a / dist) * d;
  const Vec2 n{-d.y / dist, d.x / dist};
  for (double sign : {-1.0, 1.0}) {
    const Vec2 x = mid + (sign * h) * n - eye;
    cuts.push_back(wrap_angle(std::atan2(x.y, x.x) - phi));
  }
}

}  // namespace

std::vector<double> lidar_beam_angles(int beams, double fov) {
  std::vector<double> angles(static_cast<size_t>(std::max(beams, 0)));
  if (beams == 1) {
    angles[0] = 0.0;
  } else if (fov >= 2.0 * M_PI) {
    for (int i = 0; i < beams; ++i) angles[i] = -M_PI + i * (2.0 * M_PI / beams);
  } else {
    for (int i = 0; i < beams; ++i) angles[i] = -0.5 * fov + i * (fov / (beams - 1));
  }
  return angles;
}

double sensor_heading(bool unicycle, double theta, Vec2 velocity, Vec2 position, Vec2 goal) {
  if (unicycle) return theta;
  if (abs_sq(velocity) > 1e-18) return std::atan2(velocity.y, velocity.x);
  const Vec2 to_goal = goal - position;
  return std::atan2(to_goal.y, to_goal.x);
}

bool disc_in_sight(Vec2 eye, Vec2 centre, double radius, const ObstacleView& walls, const double* other_pos,
                   const double* other_radius, const uint8_t* skip, int n_others) {
  const Vec2 dc = centre - eye;
  const double d = norm(dc);
  if (d <= radius) return true;  // the eye is inside the disc
  const Vec2 u = dc / d;
  // The ray through the centre first: in sight in most cases, and then the answer.
  if (!ray_blocked(eye, u, d - radius, walls, other_pos, other_radius, skip, n_others)) return true;

  const double phi = std::atan2(dc.y, dc.x);
  const double alpha = std::asin(radius / d);
  thread_local std::vector<double> cuts;
  cuts.clear();
  // Only an occluder nearer than the disc's centre can hide part of it (every ray reaches the disc
  // within d).
  for (int k = 0; k < walls.count; ++k) {
    const ObstacleVertex& v = walls.vertex[k];
    if (!v.own_edge) continue;
    const Vec2 p = v.point;
    const Vec2 q = v.point + v.edge;
    if (segment_distance(eye, p, q) >= d) continue;
    for (Vec2 end : {p, q}) {
      const Vec2 x = end - eye;
      cuts.push_back(wrap_angle(std::atan2(x.y, x.x) - phi));
    }
    segment_circle_cuts(eye, phi, p, q, centre, radius, cuts);
  }
  for (int k = 0; k < n_others; ++k) {
    if (skip && skip[k]) continue;
    const Vec2 c{other_pos[2 * k], other_pos[2 * k + 1]};
    const double r = other_radius[k];
    const Vec2 x = c - eye;
    const double dk = norm(x);
    if (dk <= r || dk - r >= d) continue;  // an eye inside a disc sees past it (an overlap, not a view)
    const double phik = std::atan2(x.y, x.x);
    const double half = std::asin(r / dk);
    cuts.push_back(wrap_angle(phik - half - phi));
    cuts.push_back(wrap_angle(phik + half - phi));
    circle_circle_cuts(eye, phi, centre, radius, c, r, cuts);
  }
  cuts.erase(std::remove_if(cuts.begin(), cuts.end(), [&](double a) { return !(a > -alpha && a < alpha); }),
             cuts.end());
  cuts.push_back(-alpha);
  cuts.push_back(alpha);
  std::sort(cuts.begin(), cuts.end());
  // Between two cuts, which occluders stand before the disc does not change: one ray decides the piece.
  for (size_t k = 0; k + 1 < cuts.size(); ++k) {
    if (!(cuts[k + 1] - cuts[k] > 1e-12)) continue;
    const double delta = 0.5 * (cuts[k] + cuts[k + 1]);
    const double psi = phi + delta;
    const Vec2 ray{std::cos(psi), std::sin(psi)};
    const double s = d * std::sin(delta);
    const double t_in = d * std::cos(delta) - std::sqrt(std::max(0.0, radius * radius - s * s));
    if (!ray_blocked(eye, ray, t_in, walls, other_pos, other_radius, skip, n_others)) return true;
  }
  return false;
}

namespace {

// The beams [i0, i1] whose angle may lie in [lo, hi] (relative to the heading, hi - lo <= pi), over the
// beam layout of lidar_beam_angles: calls fn(i0, i1) for each contiguous run (a run wrapping past -pi
// comes as a second call). A superset is enough: every beam is then tested exactly.
template <class Fn>
inline void for_beam_runs(double lo, double hi, int n, double fov, Fn fn) {
  if (n == 1) {
    fn(0, 0);
    return;
  }
  const bool full = fov >= 2.0 * M_PI;
  const double a0 = full ? -M_PI : -0.5 * fov;
  const double step = full ? 2.0 * M_PI / n : fov / (n - 1);
  for (double shift : {0.0, -2.0 * M_PI, 2.0 * M_PI}) {
    const double from = std::floor((lo + shift - a0) / step);
    const double to = std::ceil((hi + shift - a0) / step);
    if (to < 0.0 || from > n - 1) continue;
    fn(static_cast<int>(std::max(from, 0.0)), static_cast<int>(std::min(to, n - 1.0)));
  }
}

}  // namespace

void lidar_scan(Vec2 eye, double heading, const double* beam_cos, const double* beam_sin, int n, double range,
                const ObstacleView& walls, const double* disc_pos, const double* disc_radius, const uint8_t* skip,
                int n_discs, double* out, double fov) {
  for (int i = 0; i < n; ++i) out[i] = range;
  const double ch = std::cos(heading);
  const double sh = std::sin(heading);
  // The sensor's frame: x along the heading, so the beams' directions are the fixed table.
  auto local = [&](Vec2 p) {
    const Vec2 w = p - eye;
    return Vec2{ch * w.x + sh * w.y, -sh * w.x + ch * w.y};
  };
  for (int k = 0; k < walls.count; ++k) {
    const ObstacleVertex& v = walls.vertex[k];
    if (!v.own_edge) continue;
    // A solid polygon is counter-clockwise: from outside, a face whose interior side holds the eye is
    // behind the polygon's front faces.
    if (v.solid && det(v.edge, eye - v.point) > 0.0) continue;
    const Vec2 p = local(v.point);
    const Vec2 q = local(v.point + v.edge);
    if (segment_distance(Vec2{}, p, q) >= range) continue;
    const Vec2 e = q - p;
    const double ap = std::atan2(p.y, p.x);
    const double span = wrap_angle(std::atan2(q.y, q.x) - ap);
    const double lo = span < 0.0 ? ap + span : ap;
    const double num = det(p, e);
    for_beam_runs(lo, lo + std::abs(span), n, fov, [&](int i0, int i1) {
      for (int i = i0; i <= i1; ++i) {
        const double denom = beam_cos[i] * e.y - beam_sin[i] * e.x;
        const double t = num / denom;
        const double s = (p.x * beam_sin[i] - p.y * beam_cos[i]) / denom;
        const bool hit = t >= 0.0 && s >= 0.0 && s <= 1.0;
        out[i] = hit && t < out[i] ? t : out[i];
      }
    });
  }
  for (int k = 0; k < n_discs; ++k) {
    if (skip && skip[k]) continue;
    const Vec2 c = local(Vec2{disc_pos[2 * k], disc_pos[2 * k + 1]});
    const double r = disc_radius[k];
    const double dist_sq = abs_sq(c);
    if (dist_sq <= r * r) {
      for (int i = 0; i < n; ++i) out[i] = 0.0;
      return;
    }
    const double dist = std::sqrt(dist_sq);
    if (dist - r >= range) continue;
    const double phi = std::atan2(c.y, c.x);
    const double half = std::asin(r / dist);
    for_beam_runs(phi - half, phi + half, n, fov, [&](int i0, int i1) {
      for (int i = i0; i <= i1; ++i) {
        const double b = beam_cos[i] * c.x + beam_sin[i] * c.y;
        const double h_sq = dist_sq - b * b;
        if (b <= 0.0 || h_sq > r * r) continue;
        const double t = b - std::sqrt(r * r - h_sq);
        out[i] = t < out[i] ? t : out[i];
      }
    });
  }
}

double sensing_uniform(int64_t seed, int64_t step, int64_t index, uint64_t stream) {
  return static_cast<double>(draw_bits(seed, step, index, stream) >> 11) * 0x1.0p-53;
}

double sensing_normal(int64_t seed, int64_t step, int64_t index, uint64_t stream) {
  // Box-Muller on two independent draws (the second stream is the first's + 2^32).
  const double u1 = 1.0 - sensing_uniform(seed, step, index, stream);  // (0, 1]: log is finite
  const double u2 = sensing_uniform(seed, step, index, stream + (1ULL << 32));
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

}  // namespace socialnav
