#include "sensing.hpp"

#include <algorithm>
#include <cmath>

#include "multiversion.hpp"
#include "splitmix.hpp"

namespace socialnav {

namespace {

// The draw of (seed, step, index, stream): the four words chained into one hash (splitmix.hpp).
inline uint64_t draw_bits(int64_t seed, int64_t step, int64_t index, uint64_t stream) {
  const uint64_t h = chain64(chain64(chain64(0, static_cast<uint64_t>(seed)), static_cast<uint64_t>(step)),
                             static_cast<uint64_t>(index));
  return chain64(h, stream);
}

inline double wrap_angle(double a) { return std::remainder(a, 2.0 * M_PI); }

// Distance from `eye` to the edge [p, q] (an edge has a length: the map's preparation refuses others).
inline double segment_distance(Vec2 eye, Vec2 p, Vec2 q) { return std::sqrt(dist_sq_point_segment(p, q, eye)); }

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

// atan2 to within 1e-5 rad (a minimax polynomial of atan on [0, 1] and the octant symmetries): only
// where a scan looks for the beams an occluder may cover, each of which is then tested exactly.
inline double approx_atan2(double y, double x) {
  const double ax = std::abs(x), ay = std::abs(y);
  const double big = ax > ay ? ax : ay;
  if (big == 0.0) return 0.0;
  const double a = (ax > ay ? ay : ax) / big;
  const double q = a * a;
  double r = ((-0.0464964749 * q + 0.15931422) * q - 0.327622764) * q * a + a;
  if (ay > ax) r = 0.5 * M_PI - r;
  if (x < 0.0) r = M_PI - r;
  return y < 0.0 ? -r : r;
}

// Covers the error of approx_atan2 and the rounding of the index arithmetic, well below a beam's spacing
// at any count the settings allow.
constexpr double kAngleMargin = 1e-4;

struct BeamLayout {
  int n;
  double a0;        // angle of beam 0
  double inv_step;  // beams per radian
  bool full;        // beams over the whole circle (indices wrap)
};

inline BeamLayout beam_layout(int n, double fov) {
  if (n == 1) return {1, 0.0, 0.0, false};
  if (fov >= 2.0 * M_PI) return {n, -M_PI, n / (2.0 * M_PI), true};
  return {n, -0.5 * fov, (n - 1) / fov, false};
}

// Calls fn(i0, i1) for the runs of beams whose angle may lie in [lo, hi] (relative to the heading,
// hi - lo <= pi): a superset, since every beam is then tested exactly. Over a full circle a run that wraps
// past -pi comes as two calls.
template <class Fn>
inline void for_beam_runs(double lo, double hi, const BeamLayout& b, Fn fn) {
  if (b.n == 1) {
    fn(0, 0);
    return;
  }
  if (!b.full) {  // a sector: the interval may reach the sector from either side of +-pi
    for (double shift : {0.0, -2.0 * M_PI, 2.0 * M_PI}) {
      const auto from = static_cast<int64_t>(std::floor((lo + shift - kAngleMargin - b.a0) * b.inv_step));
      const auto to = static_cast<int64_t>(std::ceil((hi + shift + kAngleMargin - b.a0) * b.inv_step));
      const int64_t i0 = std::max<int64_t>(from, 0), i1 = std::min<int64_t>(to, b.n - 1);
      if (i0 <= i1) fn(static_cast<int>(i0), static_cast<int>(i1));
    }
    return;
  }
  const auto from = static_cast<int64_t>(std::floor((lo - kAngleMargin - b.a0) * b.inv_step));
  const auto to = static_cast<int64_t>(std::ceil((hi + kAngleMargin - b.a0) * b.inv_step));
  if (to - from + 1 >= b.n) {
    fn(0, b.n - 1);
    return;
  }
  const int64_t i0 = ((from % b.n) + b.n) % b.n;  // the run's first beam, then as far as it goes
  const int64_t i1 = i0 + (to - from);
  if (i1 < b.n) {
    fn(static_cast<int>(i0), static_cast<int>(i1));
  } else {
    fn(static_cast<int>(i0), b.n - 1);
    fn(0, static_cast<int>(i1 - b.n));
  }
}

// Beams [i0, i1] against the segment from p along e (sensor frame): where a beam crosses it nearer than
// what it has, the distance.
SOCIALNAV_AVX2_CLONE void segment_run(const double* __restrict cs, const double* __restrict sn, double* __restrict out,
                                      int i0, int i1, double px, double py, double ex, double ey) {
  const double num = px * ey - py * ex;
  for (int i = i0; i <= i1; ++i) {
    const double denom = cs[i] * ey - sn[i] * ex;
    const double t = num / denom;
    const double s = (px * sn[i] - py * cs[i]) / denom;
    const bool hit = (t >= 0.0) & (s >= 0.0) & (s <= 1.0) & (t < out[i]);
    out[i] = hit ? t : out[i];
  }
}

// Beams [i0, i1] against the disc at c (sensor frame, |c|^2 = dist_sq > r_sq, the eye outside).
SOCIALNAV_AVX2_CLONE void disc_run(const double* __restrict cs, const double* __restrict sn, double* __restrict out,
                                   int i0, int i1, double cx, double cy, double dist_sq, double r_sq) {
  for (int i = i0; i <= i1; ++i) {
    const double b = cs[i] * cx + sn[i] * cy;
    const double q = r_sq - (dist_sq - b * b);
    const double t = b - std::sqrt(q > 0.0 ? q : 0.0);
    const bool hit = (b > 0.0) & (q >= 0.0) & (t < out[i]);
    out[i] = hit ? t : out[i];
  }
}

}  // namespace

void lidar_scan(Vec2 eye, double heading, const double* beam_cos, const double* beam_sin, int n, double range,
                const ObstacleView& walls, const double* disc_pos, const double* disc_radius, const uint8_t* skip,
                int n_discs, double* out, double fov) {
  std::fill(out, out + n, range);
  const BeamLayout layout = beam_layout(n, fov);
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
    // The segment covers the angles from its clockwise end over the angle between its ends (< pi: the eye
    // is not on it); the sides come from the exact cross product, not from two rounded angles.
    const double turn = det(p, q);
    const double lo = turn >= 0.0 ? approx_atan2(p.y, p.x) : approx_atan2(q.y, q.x);
    const double sweep = approx_atan2(std::abs(turn), dot(p, q));
    const Vec2 e = q - p;
    for_beam_runs(lo, lo + sweep, layout,
                  [&](int i0, int i1) { segment_run(beam_cos, beam_sin, out, i0, i1, p.x, p.y, e.x, e.y); });
  }
  for (int k = 0; k < n_discs; ++k) {
    if (skip && skip[k]) continue;
    const Vec2 c = local(Vec2{disc_pos[2 * k], disc_pos[2 * k + 1]});
    const double r = disc_radius[k];
    const double dist_sq = abs_sq(c);
    if (dist_sq <= r * r) {
      std::fill(out, out + n, 0.0);
      return;
    }
    const double dist = std::sqrt(dist_sq);
    if (dist - r >= range) continue;
    // asin(r / d) <= (r / d) / sqrt(1 - (r / d)^2) = r / sqrt(d^2 - r^2): a bound without asin
    const double half = r / std::sqrt(dist_sq - r * r);
    const double phi = approx_atan2(c.y, c.x);
    for_beam_runs(phi - half, phi + half, layout,
                  [&](int i0, int i1) { disc_run(beam_cos, beam_sin, out, i0, i1, c.x, c.y, dist_sq, r * r); });
  }
}

namespace {

SOCIALNAV_AVX2_CLONE void to_float(const double* __restrict ranges, int n, float* __restrict out) {
  for (int i = 0; i < n; ++i) out[i] = static_cast<float>(ranges[i]);
}

}  // namespace

void store_ranges(const double* ranges, int n, float* out) { to_float(ranges, n, out); }

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
