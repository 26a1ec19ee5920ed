// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "tests/support/true_surface.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <utility>

#include "tests/support/random.h"

namespace stlrefine::test {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kInf = std::numeric_limits<double>::infinity();

double angle_between_deg(const Vec3& a, const Vec3& b) {
  return std::acos(std::clamp(dot(a, b), -1.0, 1.0)) * 180.0 / kPi;
}

//! Two unit vectors perpendicular to the unit vector d and to each other, (e1, e2, d)
//! right-handed.
std::pair<Vec3, Vec3> frame(const Vec3& d) {
  const Vec3 helper = std::abs(d.x) < 0.6 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
  const Vec3 e1 = normalized(cross(helper, d));
  return {e1, cross(d, e1)};
}

// --- planar profiles ------------------------------------------------------------------------

struct Nearest2 {
  Vec2 point;
  Vec2 normal;  //!< outward, unit
  double dist2 = kInf;
};

double dist2(Vec2 a, Vec2 b) {
  return (a.u - b.u) * (a.u - b.u) + (a.v - b.v) * (a.v - b.v);
}

Nearest2 nearest_on(const ProfilePiece& s, Vec2 q) {
  if (s.kind == ProfilePiece::Kind::Segment) {
    const double du = s.b.u - s.a.u, dv = s.b.v - s.a.v;
    const double len2 = du * du + dv * dv;
    const double t = std::clamp(((q.u - s.a.u) * du + (q.v - s.a.v) * dv) / len2, 0.0, 1.0);
    // The ends exactly, so that neighbouring pieces meet bit for bit.
    const Vec2 on = t == 0 ? s.a : t == 1 ? s.b : Vec2{s.a.u + t * du, s.a.v + t * dv};
    const double len = std::sqrt(len2);
    return {on, {dv / len, -du / len}, dist2(q, on)};
  }
  double ang = std::atan2(q.v - s.centre.v, q.u - s.centre.u);
  // Into [a0, a0 + 2 pi), then onto the arc, towards the nearer end when outside it.
  while (ang < s.a0) ang += 2 * kPi;
  while (ang >= s.a0 + 2 * kPi) ang -= 2 * kPi;
  if (ang > s.a1) ang = (ang - s.a1 < s.a0 + 2 * kPi - ang) ? s.a1 : s.a0;
  const Vec2 radial{std::cos(ang), std::sin(ang)};
  const Vec2 on{s.centre.u + s.radius * radial.u, s.centre.v + s.radius * radial.v};
  return {on, radial, dist2(q, on)};
}

double profile_scale(const std::vector<ProfilePiece>& profile) {
  double lo_u = kInf, hi_u = -kInf, lo_v = kInf, hi_v = -kInf;
  for (const ProfilePiece& s : profile)
    for (const double t : {0.0, 0.25, 0.5, 0.75, 1.0}) {
      const Vec2 p = s.at(t);
      lo_u = std::min(lo_u, p.u), hi_u = std::max(hi_u, p.u);
      lo_v = std::min(lo_v, p.v), hi_v = std::max(hi_v, p.v);
    }
  return std::hypot(hi_u - lo_u, hi_v - lo_v);
}

//! One candidate per piece of a composite surface.
struct Hit {
  Vec3 point;
  Vec3 normal;
  double dist2 = kInf;
};

//! The nearest hit; a crease where another piece's nearest point is the same point (to
//! `tol`) with a different normal.
SurfacePoint pick(const std::vector<Hit>& hits, double tol) {
  std::size_t best = 0;
  for (std::size_t i = 1; i < hits.size(); ++i)
    if (hits[i].dist2 < hits[best].dist2) best = i;
  SurfacePoint s{hits[best].point, hits[best].normal, hits[best].normal};
  for (std::size_t i = 0; i < hits.size(); ++i) {
    if (i == best || distance(hits[i].point, s.point) > tol) continue;
    if (angle_between_deg(hits[i].normal, s.normal) > 1e-7) {
      s.other_normal = hits[i].normal;
      break;
    }
  }
  return s;
}

//! Picks `count` items with probability proportional to their weights.
std::vector<std::size_t> weighted_picks(Rng& rng, const std::vector<double>& weights,
                                        std::size_t count) {
  double total = 0;
  for (const double w : weights) total += w;
  std::vector<std::size_t> out(count);
  for (std::size_t& o : out) {
    double x = rng.uniform() * total;
    o = 0;
    while (o + 1 < weights.size() && x >= weights[o]) x -= weights[o++];
  }
  return out;
}

// --- surfaces of revolution ------------------------------------------------------------------

//! Where consecutive pieces of a profile meet at an angle (the last meets the first when
//! the profile is closed): the corner and the normals of the piece ending and the piece
//! starting there.
struct ProfileCorner {
  Vec2 point;
  Vec2 normal_in, normal_out;
};

std::vector<ProfileCorner> profile_corners(const std::vector<ProfilePiece>& profile, double tol) {
  std::vector<ProfileCorner> corners;
  for (std::size_t i = 0; i < profile.size(); ++i) {
    const ProfilePiece &a = profile[i], &b = profile[(i + 1) % profile.size()];
    if (std::sqrt(dist2(a.at(1), b.at(0))) > tol) continue;  // an open end (on the axis)
    const Vec2 n0 = a.normal_at(1), n1 = b.normal_at(0);
    if (n0.u * n1.u + n0.v * n1.v < 1 - 1e-12) corners.push_back({a.at(1), n0, n1});
  }
  return corners;
}

class RevolutionSurface final : public TrueSurface {
 public:
  explicit RevolutionSurface(std::vector<ProfilePiece> profile)
      : profile_(std::move(profile)),
        tol_(1e-9 * profile_scale(profile_)),
        corners_(profile_corners(profile_, tol_)) {
    // Corners on the axis (a cone's tip) are points, not creases.
    std::erase_if(corners_, [&](const ProfileCorner& c) { return c.point.u <= tol_; });
  }

  std::optional<SurfacePoint> closest_crease_point(const Vec3& p) const override {
    const double rho = std::hypot(p.x, p.y);
    const double cx = rho > 0 ? p.x / rho : 1.0, cy = rho > 0 ? p.y / rho : 0.0;
    std::optional<SurfacePoint> best;
    double best_d2 = kInf;
    for (const ProfileCorner& c : corners_) {
      const double d2 = dist2({rho, p.z}, c.point);
      if (d2 >= best_d2) continue;
      best_d2 = d2;
      best = SurfacePoint{{c.point.u * cx, c.point.u * cy, c.point.v},
                          {c.normal_in.u * cx, c.normal_in.u * cy, c.normal_in.v},
                          {c.normal_out.u * cx, c.normal_out.u * cy, c.normal_out.v}};
    }
    return best;
  }

  SurfacePoint closest_point(const Vec3& p) const override {
    const double rho = std::hypot(p.x, p.y);
    // Azimuth: on the axis every one is as near; take the x axis.
    const double cx = rho > 0 ? p.x / rho : 1.0, cy = rho > 0 ? p.y / rho : 0.0;
    std::vector<Hit> hits;
    hits.reserve(profile_.size());
    for (const ProfilePiece& s : profile_) {
      const Nearest2 n = nearest_on(s, {rho, p.z});
      hits.push_back({{n.point.u * cx, n.point.u * cy, n.point.v},
                      {n.normal.u * cx, n.normal.u * cy, n.normal.v},
                      n.dist2});
    }
    return pick(hits, tol_);
  }

  std::vector<SurfacePoint> sample(std::uint64_t seed, std::size_t count) const override {
    Rng rng(seed);
    std::vector<double> area;
    for (const ProfilePiece& s : profile_)
      area.push_back(s.length() * s.at(0.5).u);  // about the piece's area / 2 pi
    std::vector<SurfacePoint> out;
    for (const std::size_t i : weighted_picks(rng, area, count)) {
      const double t = rng.uniform(1e-3, 1 - 1e-3);
      const double phi = rng.uniform(0, 2 * kPi);
      const Vec2 q = profile_[i].at(t), n = profile_[i].normal_at(t);
      const Vec3 normal{n.u * std::cos(phi), n.u * std::sin(phi), n.v};
      out.push_back({{q.u * std::cos(phi), q.u * std::sin(phi), q.v}, normal, normal});
    }
    return out;
  }

  double reach() const override {
    // Outward offsets meet the axis where the profile faces it (a tube's inner wall, a
    // torus's inner side): u / -n_u along the piece. (The profiles here are otherwise convex.)
    double r = kInf;
    for (const ProfilePiece& s : profile_)
      for (int k = 0; k <= 64; ++k) {
        const Vec2 q = s.at(k / 64.0), n = s.normal_at(k / 64.0);
        if (n.u < -1e-12) r = std::min(r, q.u / -n.u);
      }
    return r;
  }

 private:
  std::vector<ProfilePiece> profile_;
  double tol_;
  std::vector<ProfileCorner> corners_;
};

// --- prisms over a convex profile ------------------------------------------------------------

class ExtrusionSurface final : public TrueSurface {
 public:
  ExtrusionSurface(std::vector<ProfilePiece> profile, double y0, double y1)
      : profile_(std::move(profile)),
        y0_(y0),
        y1_(y1),
        tol_(1e-9 * profile_scale(profile_)),
        corners_(profile_corners(profile_, tol_)) {
    if (!(y0_ < y1_)) throw std::invalid_argument("extrusion_surface: y0 must be below y1");
  }

  //! Creases: the profile's corners swept from y0 to y1, and the outline of each end cap.
  std::optional<SurfacePoint> closest_crease_point(const Vec3& p) const override {
    const Vec2 q{p.x, p.z};
    const double yc = std::clamp(p.y, y0_, y1_);
    std::optional<SurfacePoint> best;
    double best_d2 = kInf;
    for (const ProfileCorner& c : corners_) {
      const double d2 = dist2(q, c.point) + (p.y - yc) * (p.y - yc);
      if (d2 >= best_d2) continue;
      best_d2 = d2;
      best = SurfacePoint{{c.point.u, yc, c.point.v},
                          {c.normal_in.u, 0, c.normal_in.v},
                          {c.normal_out.u, 0, c.normal_out.v}};
    }
    for (const ProfilePiece& s : profile_) {
      const Nearest2 n = nearest_on(s, q);
      for (const double y : {y0_, y1_}) {
        const double d2 = n.dist2 + (p.y - y) * (p.y - y);
        if (d2 >= best_d2) continue;
        best_d2 = d2;
        best = SurfacePoint{
            {n.point.u, y, n.point.v}, {0, y == y0_ ? -1.0 : 1.0, 0}, {n.normal.u, 0, n.normal.v}};
      }
    }
    return best;
  }

  SurfacePoint closest_point(const Vec3& p) const override {
    const Vec2 q{p.x, p.z};
    const double yc = std::clamp(p.y, y0_, y1_);
    std::vector<Hit> hits;
    hits.reserve(profile_.size() + 2);
    Nearest2 boundary;  // the profile's nearest boundary point, for the caps
    for (const ProfilePiece& s : profile_) {
      const Nearest2 n = nearest_on(s, q);
      if (n.dist2 < boundary.dist2) boundary = n;
      hits.push_back({{n.point.u, yc, n.point.v},
                      {n.normal.u, 0, n.normal.v},
                      n.dist2 + (p.y - yc) * (p.y - yc)});
    }
    const bool inside = inside_profile(q);
    for (const double y : {y0_, y1_}) {
      const Vec2 on = inside ? q : boundary.point;
      hits.push_back(
          {{on.u, y, on.v}, {0, y == y0_ ? -1.0 : 1.0, 0}, dist2(q, on) + (p.y - y) * (p.y - y)});
    }
    return pick(hits, tol_);
  }

  std::vector<SurfacePoint> sample(std::uint64_t seed, std::size_t count) const override {
    Rng rng(seed);
    double lo_u = kInf, hi_u = -kInf, lo_v = kInf, hi_v = -kInf;
    std::vector<double> area;
    for (const ProfilePiece& s : profile_) {
      area.push_back(s.length() * (y1_ - y0_));
      for (const double t : {0.0, 0.5, 1.0}) {
        const Vec2 a = s.at(t);
        lo_u = std::min(lo_u, a.u), hi_u = std::max(hi_u, a.u);
        lo_v = std::min(lo_v, a.v), hi_v = std::max(hi_v, a.v);
      }
    }
    const double cap_area = (hi_u - lo_u) * (hi_v - lo_v);
    area.push_back(cap_area);
    area.push_back(cap_area);
    std::vector<SurfacePoint> out;
    for (const std::size_t i : weighted_picks(rng, area, count)) {
      if (i < profile_.size()) {
        const double t = rng.uniform(1e-3, 1 - 1e-3);
        const double y = rng.uniform(y0_, y1_);
        const Vec2 q = profile_[i].at(t), n = profile_[i].normal_at(t);
        out.push_back({{q.u, y, q.v}, {n.u, 0, n.v}, {n.u, 0, n.v}});
        continue;
      }
      Vec2 q;
      do q = {rng.uniform(lo_u, hi_u), rng.uniform(lo_v, hi_v)};
      while (!inside_profile(q));
      const Vec3 n{0, i == profile_.size() ? -1.0 : 1.0, 0};
      out.push_back({{q.u, i == profile_.size() ? y0_ : y1_, q.v}, n, n});
    }
    return out;
  }

  double reach() const override { return kInf; }  // a convex solid

 private:
  //! Inside the convex profile: left of every segment; inside every arc's disc or left of
  //! its chord (arcs of at most half a turn).
  bool inside_profile(Vec2 q) const {
    for (const ProfilePiece& s : profile_) {
      const Vec2 a = s.at(0), b = s.at(1);
      const double left = (b.u - a.u) * (q.v - a.v) - (b.v - a.v) * (q.u - a.u);
      if (s.kind == ProfilePiece::Kind::Segment) {
        if (left < 0) return false;
      } else if (left < 0 && dist2(q, s.centre) > s.radius * s.radius) {
        return false;
      }
    }
    return true;
  }

  std::vector<ProfilePiece> profile_;
  double y0_, y1_;
  double tol_;
  std::vector<ProfileCorner> corners_;
};

// --- sphere, ellipsoid -----------------------------------------------------------------------

class SphereSurface final : public TrueSurface {
 public:
  SphereSurface(Vec3 centre, double radius) : centre_(centre), radius_(radius) {}

  SurfacePoint closest_point(const Vec3& p) const override {
    Vec3 n = normalized(p - centre_);
    if (n == Vec3{}) n = {0, 0, 1};
    return {centre_ + n * radius_, n, n};
  }
  std::vector<SurfacePoint> sample(std::uint64_t seed, std::size_t count) const override {
    Rng rng(seed);
    std::vector<SurfacePoint> out(count);
    for (SurfacePoint& s : out) {
      const Vec3 n = rng.unit_vector();
      s = {centre_ + n * radius_, n, n};
    }
    return out;
  }
  double reach() const override { return kInf; }

 private:
  Vec3 centre_;
  double radius_;
};

//! hypot of up to three values without overflow.
double robust_length(double a, double b, double c = 0) {
  const double m = std::max({std::abs(a), std::abs(b), std::abs(c)});
  if (m == 0) return 0;
  a /= m, b /= m, c /= m;
  return m * std::sqrt(a * a + b * b + c * c);
}

// Eberly's bisections: the root s of sum (r_i z_i / (s + r_i))^2 = 1, bracketed by s0, s1.
double root_2d(double r0, double z0, double z1, double g) {
  const double n0 = r0 * z0;
  double s0 = z1 - 1, s1 = g < 0 ? 0 : robust_length(n0, z1) - 1, s = 0;
  for (int i = 0; i < 2200; ++i) {
    s = 0.5 * (s0 + s1);
    if (s == s0 || s == s1) break;
    const double t0 = n0 / (s + r0), t1 = z1 / (s + 1);
    g = t0 * t0 + t1 * t1 - 1;
    if (g > 0)
      s0 = s;
    else if (g < 0)
      s1 = s;
    else
      break;
  }
  return s;
}

double root_3d(double r0, double r1, double z0, double z1, double z2, double g) {
  const double n0 = r0 * z0, n1 = r1 * z1;
  double s0 = z2 - 1, s1 = g < 0 ? 0 : robust_length(n0, n1, z2) - 1, s = 0;
  for (int i = 0; i < 2200; ++i) {
    s = 0.5 * (s0 + s1);
    if (s == s0 || s == s1) break;
    const double t0 = n0 / (s + r0), t1 = n1 / (s + r1), t2 = z2 / (s + 1);
    g = t0 * t0 + t1 * t1 + t2 * t2 - 1;
    if (g > 0)
      s0 = s;
    else if (g < 0)
      s1 = s;
    else
      break;
  }
  return s;
}

//! Nearest point of the ellipse (x/e0)^2 + (y/e1)^2 = 1, e0 >= e1 > 0, to (y0, y1) >= 0.
std::array<double, 2> ellipse_nearest(double e0, double e1, double y0, double y1) {
  if (y1 > 0) {
    if (y0 > 0) {
      const double z0 = y0 / e0, z1 = y1 / e1, g = z0 * z0 + z1 * z1 - 1;
      if (g == 0) return {y0, y1};
      const double r0 = (e0 / e1) * (e0 / e1);
      const double s = root_2d(r0, z0, z1, g);
      return {r0 * y0 / (s + r0), y1 / (s + 1)};
    }
    return {0, e1};
  }
  const double numer0 = e0 * y0, denom0 = e0 * e0 - e1 * e1;
  if (numer0 < denom0) {
    const double xde0 = numer0 / denom0;
    return {e0 * xde0, e1 * std::sqrt(std::max(0.0, 1 - xde0 * xde0))};
  }
  return {e0, 0};
}

//! Nearest point of the ellipsoid with semi-axes e0 >= e1 >= e2 > 0 to y >= 0 (Eberly).
std::array<double, 3> ellipsoid_nearest(const std::array<double, 3>& e,
                                        const std::array<double, 3>& y) {
  if (y[2] > 0) {
    if (y[1] > 0) {
      if (y[0] > 0) {
        const double z0 = y[0] / e[0], z1 = y[1] / e[1], z2 = y[2] / e[2];
        const double g = z0 * z0 + z1 * z1 + z2 * z2 - 1;
        if (g == 0) return y;
        const double r0 = (e[0] / e[2]) * (e[0] / e[2]), r1 = (e[1] / e[2]) * (e[1] / e[2]);
        const double s = root_3d(r0, r1, z0, z1, z2, g);
        return {r0 * y[0] / (s + r0), r1 * y[1] / (s + r1), y[2] / (s + 1)};
      }
      const auto x = ellipse_nearest(e[1], e[2], y[1], y[2]);
      return {0, x[0], x[1]};
    }
    if (y[0] > 0) {
      const auto x = ellipse_nearest(e[0], e[2], y[0], y[2]);
      return {x[0], 0, x[1]};
    }
    return {0, 0, e[2]};
  }
  const double denom0 = e[0] * e[0] - e[2] * e[2], denom1 = e[1] * e[1] - e[2] * e[2];
  const double numer0 = e[0] * y[0], numer1 = e[1] * y[1];
  if (numer0 < denom0 && numer1 < denom1) {
    const double xde0 = numer0 / denom0, xde1 = numer1 / denom1;
    const double discr = 1 - xde0 * xde0 - xde1 * xde1;
    if (discr > 0) return {e[0] * xde0, e[1] * xde1, e[2] * std::sqrt(discr)};
  }
  const auto x = ellipse_nearest(e[0], e[1], y[0], y[1]);
  return {x[0], x[1], 0};
}

class EllipsoidSurface final : public TrueSurface {
 public:
  EllipsoidSurface(double a, double b, double c) : axes_{a, b, c} {
    if (!(a > 0 && b > 0 && c > 0)) throw std::invalid_argument("ellipsoid_surface: axes > 0");
    // Eberly's case analysis wants the axes in decreasing order.
    order_ = {0, 1, 2};
    std::sort(order_.begin(), order_.end(),
              [&](std::size_t i, std::size_t j) { return axes_[i] > axes_[j]; });
  }

  SurfacePoint closest_point(const Vec3& p) const override {
    const std::array<double, 3> pc{p.x, p.y, p.z};
    std::array<double, 3> e{}, y{};
    for (std::size_t k = 0; k < 3; ++k) {
      e[k] = axes_[order_[k]];
      y[k] = std::abs(pc[order_[k]]);
    }
    const std::array<double, 3> x = ellipsoid_nearest(e, y);
    std::array<double, 3> out{};
    for (std::size_t k = 0; k < 3; ++k) out[order_[k]] = std::copysign(x[k], pc[order_[k]]);
    const Vec3 point{out[0], out[1], out[2]};
    const Vec3 n = normal_at(point);
    return {point, n, n};
  }

  std::vector<SurfacePoint> sample(std::uint64_t seed, std::size_t count) const override {
    Rng rng(seed);
    std::vector<SurfacePoint> out(count);
    for (SurfacePoint& s : out) {
      const Vec3 d = rng.unit_vector();
      const Vec3 point{axes_[0] * d.x, axes_[1] * d.y, axes_[2] * d.z};
      const Vec3 n = normal_at(point);
      s = {point, n, n};
    }
    return out;
  }
  double reach() const override { return kInf; }

 private:
  Vec3 normal_at(const Vec3& x) const {
    return normalized(
        {x.x / (axes_[0] * axes_[0]), x.y / (axes_[1] * axes_[1]), x.z / (axes_[2] * axes_[2])});
  }

  std::array<double, 3> axes_;
  std::array<std::size_t, 3> order_{};
};

// --- the star-shaped blob -------------------------------------------------------------------

//! r(d) and its gradient in R^3.
double blob_radius(double radius, const std::array<double, kBlobHarmonics>& c, const Vec3& d,
                   Vec3* gradient) {
  double value = 1;
  Vec3 g{};
  for (std::size_t k = 0; k < kBlobHarmonics; ++k) {
    Vec3 gk;
    value += c[k] * blob_harmonic(k, d, gradient ? &gk : nullptr);
    g += gk * c[k];
  }
  if (gradient) *gradient = g * radius;
  return radius * value;
}

class BlobSurface final : public TrueSurface {
 public:
  BlobSurface(double radius, const std::array<double, kBlobHarmonics>& c)
      : radius_(radius), c_(c) {}

  SurfacePoint closest_point(const Vec3& p) const override {
    const double pn = norm(p);
    const Vec3 d0 = pn > 0 ? p * (1.0 / pn) : Vec3{0, 0, 1};
    // No point nearer than the radial projection lies outside the ball B(p, D0), whose
    // directions from the centre are within alpha of d0.
    const double d0_dist = distance(surface_point(d0), p);
    const double alpha = pn > d0_dist ? std::asin(d0_dist / pn) : kPi;

    // Scan the cone on a grid; keep the best few as starting points.
    constexpr double kStep = 1.5 * kPi / 180;
    constexpr std::size_t kStarts = 4;
    std::array<std::pair<double, Vec3>, kStarts> starts;
    starts.fill({kInf, d0});
    auto offer = [&](const Vec3& d) {
      const Vec3 diff = surface_point(d) - p;
      const double f = dot(diff, diff);
      if (f >= starts.back().first) return;
      starts.back() = {f, d};
      std::sort(starts.begin(), starts.end(),
                [](const auto& a, const auto& b) { return a.first < b.first; });
    };
    offer(d0);
    if (alpha > 0.5 * kStep) {
      const auto [e1, e2] = frame(d0);
      const int rings = static_cast<int>(std::ceil(alpha / kStep));
      for (int j = 1; j <= rings; ++j) {
        const double theta = std::min(j * kStep, alpha);
        const int m = std::max(6, static_cast<int>(std::ceil(2 * kPi * std::sin(theta) / kStep)));
        for (int k = 0; k < m; ++k) {
          const double phi = 2 * kPi * k / m;
          offer(d0 * std::cos(theta) + (e1 * std::cos(phi) + e2 * std::sin(phi)) * std::sin(theta));
        }
      }
    }
    double best_f = kInf;
    Vec3 best_d = d0;
    for (const auto& [f, d] : starts) {
      if (!std::isfinite(f)) continue;
      const Vec3 polished = polish(p, d);
      const Vec3 diff = surface_point(polished) - p;
      if (dot(diff, diff) < best_f) best_f = dot(diff, diff), best_d = polished;
    }
    const Vec3 n = normal_at(best_d);
    return {surface_point(best_d), n, n};
  }

  std::vector<SurfacePoint> sample(std::uint64_t seed, std::size_t count) const override {
    Rng rng(seed);
    std::vector<SurfacePoint> out(count);
    for (SurfacePoint& s : out) {
      const Vec3 d = rng.unit_vector();
      const Vec3 n = normal_at(d);
      s = {surface_point(d), n, n};
    }
    return out;
  }

  // The generator keeps the harmonics small (r within +-40% of the radius, gentle slopes):
  // the principal radii stay above a fifth of the radius.
  double reach() const override { return 0.1 * radius_; }

 private:
  double r(const Vec3& d, Vec3* gradient = nullptr) const {
    return blob_radius(radius_, c_, d, gradient);
  }
  Vec3 surface_point(const Vec3& d) const { return blob_point(radius_, c_, d); }
  //! n ~ r d - grad_T r (the cross product of the two tangents of d -> r(d) d).
  Vec3 normal_at(const Vec3& d) const {
    Vec3 g;
    const double rv = r(d, &g);
    return normalized(d * rv - (g - d * dot(g, d)));
  }

  //! Newton on the sphere of directions for min f = |r(d) d - p|^2 / 2, in the chart
  //! d(s, t) = normalize(d0 + s e1 + t e2) around the current d0: the gradient is exact, the
  //! Hessian its central difference (Gauss-Newton's J^T J where that is not positive
  //! definite, far from the surface), each step halved until f does not grow.
  Vec3 polish(const Vec3& p, Vec3 d) const {
    auto f_of = [&](const Vec3& dd) {
      const Vec3 diff = surface_point(dd) - p;
      return 0.5 * dot(diff, diff);
    };
    double f = f_of(d);
    for (int it = 0; it < 100; ++it) {
      // Plain names, not a structured binding: clang 14 cannot capture those in a lambda.
      const auto axes = frame(d);
      const Vec3 e1 = axes.first, e2 = axes.second;
      // Gradient of f at chart coordinates (s, t); jtj: J^T J there.
      auto gradient = [&](double s, double t, std::array<double, 3>* jtj) {
        const Vec3 w = d + e1 * s + e2 * t;
        const double len = norm(w);
        const Vec3 dd = w * (1 / len);
        Vec3 g;
        const double rv = r(dd, &g);
        const Vec3 res = dd * rv - p;
        std::array<double, 2> out{};
        std::array<Vec3, 2> j;
        for (int k = 0; k < 2; ++k) {
          const Vec3 e = k ? e2 : e1;
          const Vec3 dd_k = (e - dd * dot(dd, e)) * (1 / len);  // d(dd)/ds, d(dd)/dt
          j[k] = dd_k * rv + dd * dot(g, dd_k);
          out[k] = dot(j[k], res);
        }
        if (jtj) *jtj = {dot(j[0], j[0]), dot(j[0], j[1]), dot(j[1], j[1])};
        return out;
      };
      std::array<double, 3> gn{};
      const auto g0 = gradient(0, 0, &gn);
      constexpr double h = 1e-5;
      const auto gsp = gradient(h, 0, nullptr), gsm = gradient(-h, 0, nullptr);
      const auto gtp = gradient(0, h, nullptr), gtm = gradient(0, -h, nullptr);
      double h11 = (gsp[0] - gsm[0]) / (2 * h), h22 = (gtp[1] - gtm[1]) / (2 * h);
      double h12 = 0.5 * ((gsp[1] - gsm[1]) / (2 * h) + (gtp[0] - gtm[0]) / (2 * h));
      if (!(h11 > 0 && h11 * h22 - h12 * h12 > 0)) h11 = gn[0], h12 = gn[1], h22 = gn[2];
      const double det = h11 * h22 - h12 * h12;
      if (!(det > 0)) break;
      const double s = -(g0[0] * h22 - g0[1] * h12) / det, t = -(h11 * g0[1] - h12 * g0[0]) / det;
      double step = 1;
      bool moved = false;
      for (int halving = 0; halving < 60; ++halving, step *= 0.5) {
        const Vec3 dn = normalized(d + (e1 * s + e2 * t) * step);
        const double fn = f_of(dn);
        if (fn <= f) {
          moved = dn != d;
          d = dn, f = fn;
          break;
        }
      }
      if (!moved || std::hypot(s, t) * step < 1e-14) break;
    }
    return d;
  }

  double radius_;
  std::array<double, kBlobHarmonics> c_;
};

// --- rounded box -----------------------------------------------------------------------------

class RoundedBoxSurface final : public TrueSurface {
 public:
  RoundedBoxSurface(Vec3 half_extent, double radius)
      : inner_{half_extent.x - radius, half_extent.y - radius, half_extent.z - radius},
        radius_(radius) {
    if (!(radius > 0 && inner_[0] > 0 && inner_[1] > 0 && inner_[2] > 0))
      throw std::invalid_argument("rounded_box_surface: 0 < radius < every half extent");
  }

  SurfacePoint closest_point(const Vec3& p) const override {
    const std::array<double, 3> pc{p.x, p.y, p.z};
    std::array<double, 3> q{};
    for (int k = 0; k < 3; ++k) q[k] = std::clamp(pc[k], -inner_[k], inner_[k]);
    const Vec3 out{pc[0] - q[0], pc[1] - q[1], pc[2] - q[2]};
    if (out != Vec3{}) {
      // Outside the inner box: straight out from its nearest point by the radius.
      const Vec3 n = normalized(out);
      const Vec3 point = Vec3{q[0], q[1], q[2]} + n * radius_;
      return {point, n, n};
    }
    // Inside the inner box: through its nearest face.
    int axis = 0;
    for (int k = 1; k < 3; ++k)
      if (inner_[k] - std::abs(pc[k]) < inner_[axis] - std::abs(pc[axis])) axis = k;
    const double sign = pc[axis] < 0 ? -1.0 : 1.0;
    std::array<double, 3> point = pc, n{0, 0, 0};
    point[axis] = sign * (inner_[axis] + radius_);
    n[axis] = sign;
    return {{point[0], point[1], point[2]}, {n[0], n[1], n[2]}, {n[0], n[1], n[2]}};
  }

  std::vector<SurfacePoint> sample(std::uint64_t seed, std::size_t count) const override {
    // Pieces: 6 faces, 12 fillets, 8 corners, each a point of the inner box's face, edge
    // or vertex pushed out by the radius along a normal of that feature.
    Rng rng(seed);
    const double pi_r = kPi * radius_;
    std::vector<double> area;
    for (int axis = 0; axis < 3; ++axis) {
      const double face = 4 * inner_[(axis + 1) % 3] * inner_[(axis + 2) % 3];
      area.insert(area.end(), {face, face});
    }
    for (int axis = 0; axis < 3; ++axis) area.push_back(4 * (2 * inner_[axis]) * pi_r / 2);
    area.push_back(8 * pi_r * radius_ / 2);
    std::vector<SurfacePoint> out;
    for (const std::size_t piece : weighted_picks(rng, area, count)) {
      std::array<double, 3> q{}, n{};
      for (int k = 0; k < 3; ++k) q[k] = rng.uniform(-inner_[k], inner_[k]);
      if (piece < 6) {
        const auto axis = piece / 2;
        const double sign = piece % 2 ? 1.0 : -1.0;
        q[axis] = sign * inner_[axis];
        n[axis] = sign;
      } else if (piece < 9) {
        const auto axis = piece - 6, a = (axis + 1) % 3, b = (axis + 2) % 3;
        const double sa = rng.uniform() < 0.5 ? -1.0 : 1.0, sb = rng.uniform() < 0.5 ? -1.0 : 1.0;
        const double psi = rng.uniform(1e-3, kPi / 2 - 1e-3);
        q[a] = sa * inner_[a], q[b] = sb * inner_[b];
        n[a] = sa * std::cos(psi), n[b] = sb * std::sin(psi);
      } else {
        const Vec3 d = rng.unit_vector();
        const std::array<double, 3> dc{d.x, d.y, d.z};
        for (int k = 0; k < 3; ++k) {
          const double sign = rng.uniform() < 0.5 ? -1.0 : 1.0;
          q[k] = sign * inner_[k];
          n[k] = sign * std::abs(dc[k]);
        }
      }
      const Vec3 normal{n[0], n[1], n[2]};
      out.push_back({Vec3{q[0], q[1], q[2]} + normal * radius_, normal, normal});
    }
    return out;
  }
  double reach() const override { return kInf; }

 private:
  std::array<double, 3> inner_;
  double radius_;
};

}  // namespace

double normal_angle_deg(const SurfacePoint& s, const Vec3& n) {
  if (!s.on_crease()) return angle_between_deg(n, s.normal);
  // The normals at a crease fill the arc between the two: n's angle to that arc.
  const Vec3 m = normalized(cross(s.normal, s.other_normal));
  const Vec3 in_plane = n - m * dot(n, m);
  if (dot(cross(s.normal, in_plane), m) >= 0 && dot(cross(in_plane, s.other_normal), m) >= 0) {
    const double len = norm(in_plane);
    return len > 0 ? std::atan2(std::abs(dot(n, m)), len) * 180.0 / kPi : 90.0;
  }
  return std::min(angle_between_deg(n, s.normal), angle_between_deg(n, s.other_normal));
}

double face_truth_angle_deg(const TrueSurface& surface, const Vec3& n, const Vec3& a, const Vec3& b,
                            const Vec3& c, double crease_snap) {
  double best = 180;
  for (const Vec3& p : {(a + b + c) * (1.0 / 3.0), a, b, c}) {
    SurfacePoint s = surface.closest_point(p);
    // A point at most twice as far from a crease as from the surface is at the crease on the
    // scale of its own error: a flat cap's face whose corners the rim's curve rule put
    // 0.0002-0.03 mm past a cone's rim lies in the cap's plane, and its closest points are on
    // the side wall, 1.07x nearer than the rim (the side's normal is 68 degrees from it).
    if (!s.on_crease())
      if (const auto crease = surface.closest_crease_point(p);
          crease && (distance(crease->point, s.point) <= crease_snap ||
                     distance(crease->point, p) <= 2 * distance(s.point, p)))
        s = *crease;
    best = std::min(best, normal_angle_deg(s, n));
  }
  return best;
}

double sampled_rms_distance(const Mesh& m, const TrueSurface& surface, int k) {
  double sum = 0, area = 0;
  for (std::uint32_t f = 0; f < m.num_faces(); ++f) {
    const auto [i, j, l] = m.face_vertices(FaceId(f));
    const Vec3 a = m.position(i), b = m.position(j), c = m.position(l);
    const double face_area = 0.5 * norm(triangle_normal(a, b, c));
    double face_sum = 0;
    for (int r = 0; r < k; ++r) {
      for (int s = 0; s + r < k; ++s) {
        // The upright sub-triangle (r, s) and, when there is one, the inverted one.
        for (int inverted = 0; inverted < 2; ++inverted) {
          if (inverted && r + s + 1 >= k) continue;
          const double u = (r + (inverted ? 2.0 : 1.0) / 3.0) / k;
          const double v = (s + (inverted ? 2.0 : 1.0) / 3.0) / k;
          const Vec3 p = a + u * (b - a) + v * (c - a);
          const double d = distance(p, surface.closest_point(p).point);
          face_sum += d * d;
        }
      }
    }
    sum += face_area * face_sum / (k * k);
    area += face_area;
  }
  return std::sqrt(sum / area);
}

std::size_t faces_off_truth(const Mesh& m, const TrueSurface& surface, double limit,
                            double crease_snap) {
  std::size_t off = 0;
  for (std::uint32_t f = 0; f < m.num_faces(); ++f) {
    const Vec3 n = normalized(m.face_normal(FaceId(f)));
    if (n == Vec3{}) continue;
    const auto [a, b, c] = m.face_vertices(FaceId(f));
    off += face_truth_angle_deg(surface, n, m.position(a), m.position(b), m.position(c),
                                crease_snap) > limit;
  }
  return off;
}

std::optional<SurfacePoint> TrueSurface::closest_crease_point(const Vec3&) const {
  return std::nullopt;
}

double TrueSurface::signed_distance(const Vec3& p) const {
  const SurfacePoint s = closest_point(p);
  const double d = distance(p, s.point);
  return dot(p - s.point, s.normal + s.other_normal) < 0 ? -d : d;
}

ProfilePiece ProfilePiece::segment(Vec2 a, Vec2 b) {
  ProfilePiece s;
  s.kind = Kind::Segment;
  s.a = a, s.b = b;
  return s;
}

ProfilePiece ProfilePiece::arc(Vec2 centre, double radius, double a0, double a1) {
  if (!(radius > 0 && a0 < a1 && a1 <= a0 + 2 * kPi + 1e-12))
    throw std::invalid_argument("ProfilePiece::arc: radius > 0, a0 < a1 <= a0 + 2 pi");
  ProfilePiece s;
  s.kind = Kind::Arc;
  s.centre = centre, s.radius = radius, s.a0 = a0, s.a1 = a1;
  s.a = s.at(0), s.b = s.at(1);
  return s;
}

Vec2 ProfilePiece::at(double t) const {
  if (kind == Kind::Segment) {
    if (t == 0) return a;
    if (t == 1) return b;
    return {a.u + t * (b.u - a.u), a.v + t * (b.v - a.v)};
  }
  const double ang = a0 + t * (a1 - a0);
  return {centre.u + radius * std::cos(ang), centre.v + radius * std::sin(ang)};
}

Vec2 ProfilePiece::normal_at(double t) const {
  if (kind == Kind::Segment) {
    const double du = b.u - a.u, dv = b.v - a.v, len = std::hypot(du, dv);
    return {dv / len, -du / len};
  }
  const double ang = a0 + t * (a1 - a0);
  return {std::cos(ang), std::sin(ang)};
}

double ProfilePiece::length() const {
  return kind == Kind::Segment ? std::hypot(b.u - a.u, b.v - a.v) : radius * (a1 - a0);
}

std::shared_ptr<const TrueSurface> revolution_surface(std::vector<ProfilePiece> profile) {
  return std::make_shared<RevolutionSurface>(std::move(profile));
}

std::shared_ptr<const TrueSurface> extrusion_surface(std::vector<ProfilePiece> profile, double y0,
                                                     double y1) {
  return std::make_shared<ExtrusionSurface>(std::move(profile), y0, y1);
}

std::shared_ptr<const TrueSurface> sphere_surface(Vec3 centre, double radius) {
  return std::make_shared<SphereSurface>(centre, radius);
}

std::shared_ptr<const TrueSurface> ellipsoid_surface(double a, double b, double c) {
  return std::make_shared<EllipsoidSurface>(a, b, c);
}

std::shared_ptr<const TrueSurface> blob_surface(double radius,
                                                const std::array<double, kBlobHarmonics>& c) {
  return std::make_shared<BlobSurface>(radius, c);
}

std::shared_ptr<const TrueSurface> rounded_box_surface(Vec3 half_extent, double radius) {
  return std::make_shared<RoundedBoxSurface>(half_extent, radius);
}

Vec3 blob_point(double radius, const std::array<double, kBlobHarmonics>& c, const Vec3& d) {
  return d * blob_radius(radius, c, d, nullptr);
}

double blob_harmonic(std::size_t k, const Vec3& d, Vec3* gradient) {
  const double x = d.x, y = d.y, z = d.z;
  Vec3 g;
  double h = 0;
  switch (k) {
    case 0:  // l = 1
      h = z, g = {0, 0, 1};
      break;
    case 1:  // l = 2
      h = x * y, g = {y, x, 0};
      break;
    case 2:
      h = 1.5 * z * z - 0.5, g = {0, 0, 3 * z};
      break;
    case 3:
      h = x * z, g = {z, 0, x};
      break;
    case 4:  // l = 3
      h = x * x * x - 3 * x * y * y, g = {3 * x * x - 3 * y * y, -6 * x * y, 0};
      break;
    case 5:
      h = 0.5 * y * (5 * z * z - 1), g = {0, 0.5 * (5 * z * z - 1), 5 * y * z};
      break;
    case 6:
      h = 3 * x * y * z, g = {3 * y * z, 3 * x * z, 3 * x * y};
      break;
    default:
      throw std::out_of_range("blob_harmonic: k < kBlobHarmonics");
  }
  if (gradient) *gradient = g;
  return h;
}

}  // namespace stlrefine::test
