// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "bench/fidelity/true_surface.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace stlrefine::fidelity {
namespace {

Vec2 to_meridian(const Vec3& p) {
  return {std::hypot(p.x, p.y), p.z};
}

//! Lifts a meridian-plane direction back to 3-D at p's azimuth.
Vec3 to_space(const Vec3& p, Vec2 d) {
  const double rho = std::hypot(p.x, p.y);
  if (rho == 0) return {0, 0, d.z};  // on the axis: pieces there have a purely axial normal
  return {d.r * p.x / rho, d.r * p.y / rho, d.z};
}

struct Nearest {
  double distance;
  Vec2 normal;  //!< outward, unit
};

Nearest nearest_on(const ProfilePiece& s, Vec2 q) {
  if (s.kind == ProfilePiece::Kind::Segment) {
    const double dr = s.b.r - s.a.r, dz = s.b.z - s.a.z;
    const double len2 = dr * dr + dz * dz;
    double t = ((q.r - s.a.r) * dr + (q.z - s.a.z) * dz) / len2;
    t = std::clamp(t, 0.0, 1.0);
    const double len = std::sqrt(len2);
    return {std::hypot(q.r - (s.a.r + t * dr), q.z - (s.a.z + t * dz)), {dz / len, -dr / len}};
  }
  const double pi = std::numbers::pi;
  double ang = std::atan2(q.z - s.centre.z, q.r - s.centre.r);
  // Bring the angle into [a0, a0 + 2 pi) and clamp to the arc, towards the nearer end.
  while (ang < s.a0) ang += 2 * pi;
  while (ang >= s.a0 + 2 * pi) ang -= 2 * pi;
  if (ang > s.a1) ang = (ang - s.a1 < s.a0 + 2 * pi - ang) ? s.a1 : s.a0;
  const Vec2 radial{std::cos(ang), std::sin(ang)};
  const Vec2 on{s.centre.r + s.radius * radial.r, s.centre.z + s.radius * radial.z};
  return {std::hypot(q.r - on.r, q.z - on.z), radial};
}

double angle_deg(const Vec3& a, const Vec3& b) {
  const double c = std::clamp(dot(a, b), -1.0, 1.0);
  return std::acos(c) * 180.0 / std::numbers::pi;
}

}  // namespace

Closest TrueSurface::closest(const Vec3& p) const {
  const Vec2 q = to_meridian(p);
  Closest best{std::numeric_limits<double>::infinity(), 0};
  for (std::size_t i = 0; i < pieces_.size(); ++i) {
    const double d = nearest_on(pieces_[i], q).distance;
    if (d < best.distance) best = {d, i};
  }
  return best;
}

Vec3 TrueSurface::normal(const Vec3& p, std::size_t i) const {
  return to_space(p, nearest_on(pieces_[i], to_meridian(p)).normal);
}

double TrueSurface::normal_angle_deg(const Vec3& p, const Vec3& n) const {
  const Vec2 q = to_meridian(p);
  const double d = closest(p).distance;
  // Ties (within rounding) mean the closest point is where pieces meet: take the best.
  const double tie = 1e-9 * (1.0 + d);
  double best = 180.0;
  for (std::size_t i = 0; i < pieces_.size(); ++i) {
    const Nearest nr = nearest_on(pieces_[i], q);
    if (nr.distance <= d + tie) best = std::min(best, angle_deg(n, to_space(p, nr.normal)));
  }
  return best;
}

double TrueSurface::rim_distance(const Vec3& p) const {
  const Vec2 q = to_meridian(p);
  double best = std::numeric_limits<double>::infinity();
  auto consider = [&](Vec2 c) { best = std::min(best, std::hypot(q.r - c.r, q.z - c.z)); };
  for (const ProfilePiece& s : pieces_) {
    // Rims are the ends of segments that do not lie on the axis (cap centres are not rims).
    if (s.kind != ProfilePiece::Kind::Segment) continue;
    if (s.a.r > 0) consider(s.a);
    if (s.b.r > 0) consider(s.b);
  }
  return best;
}

double TrueSurface::cap_plane_distance(const Vec3& p, std::size_t piece) const {
  return std::abs(p.z - pieces_[piece].a.z);
}

}  // namespace stlrefine::fidelity
