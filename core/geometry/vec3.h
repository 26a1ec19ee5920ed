// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <cmath>

namespace stlrefine {

//! A plain 3-vector of doubles: all stencils compute in double (spec section 0).
struct Vec3 {
  double x = 0, y = 0, z = 0;

  constexpr Vec3() = default;
  constexpr Vec3(double x_, double y_, double z_) : x(x_), y(y_), z(z_) {}

  constexpr Vec3& operator+=(const Vec3& o) {
    x += o.x, y += o.y, z += o.z;
    return *this;
  }
  constexpr Vec3& operator-=(const Vec3& o) {
    x -= o.x, y -= o.y, z -= o.z;
    return *this;
  }
  constexpr Vec3& operator*=(double s) {
    x *= s, y *= s, z *= s;
    return *this;
  }
  friend constexpr Vec3 operator+(Vec3 a, const Vec3& b) { return a += b; }
  friend constexpr Vec3 operator-(Vec3 a, const Vec3& b) { return a -= b; }
  friend constexpr Vec3 operator-(const Vec3& a) { return {-a.x, -a.y, -a.z}; }
  friend constexpr Vec3 operator*(Vec3 a, double s) { return a *= s; }
  friend constexpr Vec3 operator*(double s, Vec3 a) { return a *= s; }
  friend constexpr bool operator==(const Vec3& a, const Vec3& b) {
    return a.x == b.x && a.y == b.y && a.z == b.z;
  }
  friend constexpr bool operator!=(const Vec3& a, const Vec3& b) { return !(a == b); }
};

constexpr double dot(const Vec3& a, const Vec3& b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
constexpr Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double norm(const Vec3& a) {
  return std::sqrt(dot(a, a));
}
inline double distance(const Vec3& a, const Vec3& b) {
  return norm(a - b);
}
inline bool is_finite(const Vec3& a) {
  return std::isfinite(a.x) && std::isfinite(a.y) && std::isfinite(a.z);
}
//! Unit vector, or the zero vector when `a` has no direction.
inline Vec3 normalized(const Vec3& a) {
  const double n = norm(a);
  return n > 0 ? a * (1.0 / n) : Vec3{};
}
//! Whether directions a and b (any lengths) are more than acos(cos_limit) apart; false when
//! either has no direction. Compares without square roots of each or a division.
inline bool turned_past(const Vec3& a, const Vec3& b, double cos_limit) {
  const double scale = std::sqrt(dot(a, a) * dot(b, b));
  return scale > 0 && dot(a, b) < cos_limit * scale;
}
//! Twice the area vector of triangle (a, b, c): its direction is the face normal.
inline Vec3 triangle_normal(const Vec3& a, const Vec3& b, const Vec3& c) {
  return cross(b - a, c - a);
}

}  // namespace stlrefine
