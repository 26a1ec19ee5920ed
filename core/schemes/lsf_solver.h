// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// LSF's fit of one sample (lsf.h, spec 5): the damped least-squares quadric of a vertex's
// ring or sector, its normal equations and their 5x5 solve. Internal to the lsf*.cpp files:
// the stencil (lsf.cpp) and the batch kernels (lsf_kernels.cpp) share it.

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <vector>

#include "core/schemes/lsf.h"
#include "core/schemes/lsf_fast_math.h"

namespace stlrefine::lsf {

using Mat5 = std::array<std::array<double, 5>, 5>;  // [col][row]; the lower part is read

using Coefficients = std::array<Vec3, 5>;  // c1..c5

// The normal equations of the fit, summed over the sample: S^T S for rows (u, v, u^2/2,
// uv, v^2/2) has 12 distinct entries up to factors 1/2 and 1/4 (the monomials of degree 2
// to 4 in u, v); S^T q has 5 rows of 3.
struct NormalEquations {
  // u^2, uv, v^2, u^3, u^2 v, u v^2, v^3, u^4, u^3 v, u^2 v^2, u v^3, v^4
  double s[12];
  Coefficients q;  // sum of (P_i - V) times u, v, u^2/2, uv, v^2/2
  double radius_sum;

  // S^T S, lower part ([col][row], row >= col).
  Mat5 matrix() const {
    Mat5 n{};
    n[0] = {s[0], s[1], 0.5 * s[3], s[4], 0.5 * s[5]};
    n[1] = {0, s[2], 0.5 * s[4], s[5], 0.5 * s[6]};
    n[2] = {0, 0, 0.25 * s[7], 0.5 * s[8], 0.25 * s[9]};
    n[3] = {0, 0, 0, s[9], 0.5 * s[10]};
    n[4] = {0, 0, 0, 0, 0.25 * s[11]};
    return n;
  }
};

//! fast_solve's floor on the determinant of the Jacobi-scaled damped matrix (the certificate
//! that the general path would decide alike, see lsf_solver.cpp); the batch kernels certify
//! with it too. 2.1e-6 * ((5 + 3e-7) / 4)^4 = 5.13e-6, rounded up.
inline constexpr double kDetFloor = 6e-6;

//! Solves the damped normal equations of `count` points (spec 5 gap 1): the certified fast
//! path from five points on, else the general one. False for a degenerate sample.
bool solve_fit(const NormalEquations& e, std::size_t count, double mu, Coefficients& c);

using lsf_math::V2d;

inline V2d load2(const double* p) {
  V2d v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline void store2(double* p, V2d v) {
  std::memcpy(p, &v, sizeof v);
}

// A vertex's ring (or one sector of it) in structure-of-arrays form: the offsets P_i - V
// and, once fitted, the Welch-Witkin parameters (u_i, v_i) and radii r_i. The kernels
// below take two points at a time (lsf_math::V2d), so every array has room for padding.
struct Sample {
  std::vector<double> data;
  std::size_t size = 0, capacity = 0;
  double *x = nullptr, *y = nullptr, *z = nullptr, *u = nullptr, *v = nullptr, *r = nullptr,
         *phi = nullptr;
  std::vector<HalfedgeId> spoke;    // the outgoing half-edge to point i (ring buffers)
  std::vector<std::uint8_t> sharp;  // whether it is sharp; only read when any_sharp
  bool any_sharp = false;

  static constexpr std::size_t kArrays = 7;
  void reserve(std::size_t n) {
    if (n + 2 <= capacity) return;
    const std::size_t grown_capacity = std::max<std::size_t>(2 * n + 2, 32);
    std::vector<double> grown(kArrays * grown_capacity);
    for (std::size_t a = 0; a < 3; ++a)  // keep x, y, z
      std::copy_n(data.begin() + static_cast<std::ptrdiff_t>(a * capacity), size,
                  grown.begin() + static_cast<std::ptrdiff_t>(a * grown_capacity));
    data.swap(grown);
    capacity = grown_capacity;
    spoke.resize(capacity);
    sharp.resize(capacity);
    x = data.data(), y = x + capacity, z = y + capacity, u = z + capacity, v = u + capacity;
    r = v + capacity, phi = r + capacity;
  }
  void clear() { size = 0, any_sharp = false; }
  void push(const Vec3& d, HalfedgeId h = HalfedgeId(), bool is_sharp = false) {
    if (size + 2 >= capacity) reserve(size + 1);
    x[size] = d.x, y[size] = d.y, z[size] = d.z;
    spoke[size] = h;
    sharp[size] = is_sharp;
    any_sharp |= is_sharp;
    ++size;
  }
  // Points begin..begin+count of another sample.
  void assign(const Sample& from, std::size_t begin, std::size_t count) {
    clear();
    reserve(count);
    std::copy_n(from.x + begin, count, x);
    std::copy_n(from.y + begin, count, y);
    std::copy_n(from.z + begin, count, z);
    size = count;
  }
};

// A fitted sample: valid == false for a degenerate one.
struct SampleFit {
  const Sample* sample;
  bool valid;
  Coefficients c;

  QuadricFit quadric(const Vec3& origin) const {
    QuadricFit fit;
    fit.origin = origin;
    if (!valid) return fit;
    fit.c = c;
    fit.valid = true;
    return fit;
  }
  // Calls out(i, offset) with the fit at half of point i's parameter, relative to V:
  // s(u/2, v/2) - V = (c1 u + c2 v) / 2 + (c3 u^2 + 2 c4 uv + c5 v^2) / 8; the chord
  // midpoint offset (P_i - V) / 2 when the fit is not valid.
  template <class Out>
  void half_points(Out&& out) const {
    const Sample& s = *sample;
    if (!valid) {
      for (std::size_t i = 0; i < s.size; ++i) out(i, 0.5 * Vec3(s.x[i], s.y[i], s.z[i]));
      return;
    }
    const Vec3 h0 = 0.5 * c[0], h1 = 0.5 * c[1], h2 = 0.125 * c[2], h3 = 0.25 * c[3],
               h4 = 0.125 * c[4];
    for (std::size_t i = 0; i < s.size; i += 2) {
      const V2d a = load2(s.u + i), b = load2(s.v + i);
      const V2d a2 = a * a, ab = a * b, b2 = b * b;
      const V2d px = a * h0.x + b * h1.x + a2 * h2.x + ab * h3.x + b2 * h4.x;
      const V2d py = a * h0.y + b * h1.y + a2 * h2.y + ab * h3.y + b2 * h4.y;
      const V2d pz = a * h0.z + b * h1.z + a2 * h2.z + ab * h3.z + b2 * h4.z;
      out(i, Vec3(px[0], py[0], pz[0]));
      if (i + 1 < s.size) out(i + 1, Vec3(px[1], py[1], pz[1]));
    }
  }
};

//! The sample's Welch-Witkin parameters (closed ring or open fan, angles scaled to
//! total_angle; 0 keeps them) and its damped fit.
SampleFit fit_sample(Sample& s, bool closed, double total_angle, double mu = 1e-9);

//! Per-thread samples, cleared: the ring being walked, and one sector of it.
Sample& ring_sample();
Sample& sector_sample();

}  // namespace stlrefine::lsf
