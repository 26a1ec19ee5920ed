// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/lsf_kernels.h"

#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <utility>

#include "core/schemes/lsf_fast_math.h"
#include "core/schemes/lsf_rules.h"
#include "core/schemes/lsf_solver.h"

// -Wpsabi (32-byte vectors in internal signatures) is silenced by lsf_fast_math.h for its
// includers.

namespace stlrefine::lsf {

namespace {

using lsf_math::V4d;
using lsf_math::V4i;

[[gnu::always_inline]] inline V4d load4(const double* p) {
  V4d v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

// Lane l of a solve the fast path could not certify: solve_fit on that lane's sums. Out of
// line, so the batch kernels below do not carry a copy of the general path.
// (Everything it takes is passed by reference: a V4d by value would be passed in a register
// by the AVX2 kernel and in memory by this baseline-compiled function.)
[[gnu::noinline]] bool solve_lane(const V4d (&sum)[12], const V4d (&rhs)[5][3], const V4d& radii,
                                  std::size_t n, int l, V4d (&c)[5][3]) {
  NormalEquations e;
  for (int k = 0; k < 12; ++k) e.s[k] = sum[k][l];
  for (int k = 0; k < 5; ++k) e.q[k] = Vec3(rhs[k][0][l], rhs[k][1][l], rhs[k][2][l]);
  e.radius_sum = radii[l];
  Coefficients fit;
  const bool ok = solve_fit(e, n, 1e-9, fit);
  for (int k = 0; k < 5; ++k) c[k][0][l] = fit[k].x, c[k][1][l] = fit[k].y, c[k][2][l] = fit[k].z;
  return ok;
}

// Sums terms(i) over i < n as the pair kernels do: (t0 + t2 + ...) + (t1 + t3 + ...).
template <int K, class Terms>
[[gnu::always_inline]] inline void pair_sums(std::size_t n, V4d (&out)[K], Terms&& terms) {
  V4d even[K] = {}, odd[K] = {};
  std::size_t i = 0;
  for (; i + 1 < n; i += 2) {
    V4d t[K];
    terms(i, t);
    for (int k = 0; k < K; ++k) even[k] += t[k];
    terms(i + 1, t);
    for (int k = 0; k < K; ++k) odd[k] += t[k];
  }
  if (i < n) {
    V4d t[K];
    terms(i, t);
    for (int k = 0; k < K; ++k) even[k] += t[k];
  }
  for (int k = 0; k < K; ++k) out[k] = even[k] + odd[k];
}

[[gnu::always_inline]] inline V4d min4(V4d a, V4d b) {  // std::min, lane by lane
  return lsf_math::detail::select(b < a, b, a);
}
[[gnu::always_inline]] inline V4d max4(V4d a, V4d b) {  // std::max, lane by lane
  return lsf_math::detail::select(a < b, b, a);
}

// general_solve for fewer than five points (no conditioning test; spec 5 gap 1 damping), on
// every lane at once: Ldlt5's pivoted factorisation and solve with the same operations in
// the same order, as long as the four lanes choose the same pivots and none of them is zero
// (Ldlt5's special cases). Returns false, with nothing written, otherwise: the caller then
// solves lane by lane.
[[gnu::always_inline]] inline bool general_solve_small(const V4d (&sum)[12], const V4d (&rhs)[5][3],
                                                       V4d damping, V4d (&c)[5][3], V4i& valid) {
  using lsf_math::detail::select;
  // NormalEquations::matrix() plus the damping, lower part, a[col][row].
  V4d a[5][5];
  const V4d zero = {0, 0, 0, 0};
  for (auto& col : a)
    for (V4d& x : col) x = zero;
  a[0][0] = sum[0], a[0][1] = sum[1], a[0][2] = 0.5 * sum[3], a[0][3] = sum[4];
  a[0][4] = 0.5 * sum[5];
  a[1][1] = sum[2], a[1][2] = 0.5 * sum[4], a[1][3] = sum[5], a[1][4] = 0.5 * sum[6];
  a[2][2] = 0.25 * sum[7], a[2][3] = 0.5 * sum[8], a[2][4] = 0.25 * sum[9];
  a[3][3] = sum[9], a[3][4] = 0.5 * sum[10];
  a[4][4] = 0.25 * sum[11];
  for (int k = 2; k < 5; ++k) a[k][k] += damping;
  auto at = [&](int r, int col) -> V4d& { return a[col][r]; };
  int perm[5];
  V4i positive = {-1, -1, -1, -1};
  for (int k = 0; k < 5; ++k) {
    V4i p = {k, k, k, k};
    V4d biggest = lsf_math::detail::abs(at(k, k));
    for (int i = k + 1; i < 5; ++i) {
      const V4d candidate = lsf_math::detail::abs(at(i, i));
      const V4i larger = candidate > biggest;
      biggest = select(larger, candidate, biggest);
      p = (p & ~larger) | (V4i{i, i, i, i} & larger);
    }
    if (!(p[0] == p[1] && p[0] == p[2] && p[0] == p[3])) return false;
    const int q = static_cast<int>(p[0]);
    perm[k] = q;
    if (q != k) {
      for (int j = 0; j < k; ++j) std::swap(at(k, j), at(q, j));
      for (int i = q + 1; i < 5; ++i) std::swap(at(i, k), at(i, q));
      std::swap(at(k, k), at(q, q));
      for (int i = k + 1; i < q; ++i) std::swap(at(i, k), at(q, i));
    }
    if (k > 0) {
      V4d temp[5];
      for (int j = 0; j < k; ++j) temp[j] = at(j, j) * at(k, j);
      V4d t = at(k, 0) * temp[0];
      for (int j = 1; j < k; ++j) t += at(k, j) * temp[j];
      at(k, k) -= t;
      for (int i = k + 1; i < 5; ++i) {
        V4d sum_i = zero;
        for (int j = 0; j < k; ++j) sum_i += at(i, j) * temp[j];
        at(i, k) -= sum_i;
      }
    }
    const V4d akk = at(k, k);
    const V4i pivot_valid = lsf_math::detail::abs(akk) > 0;
    if (!(pivot_valid[0] && pivot_valid[1] && pivot_valid[2] && pivot_valid[3])) return false;
    for (int i = k + 1; i < 5; ++i) at(i, k) /= akk;
    positive &= ~(akk < 0);
  }
  // Ldlt5::solve on the three right-hand sides.
  V4d x[5][3];
  for (int k = 0; k < 5; ++k)
    for (int j = 0; j < 3; ++j) x[k][j] = rhs[k][j];
  for (int k = 0; k < 5; ++k)
    if (perm[k] != k)
      for (int j = 0; j < 3; ++j) std::swap(x[k][j], x[perm[k]][j]);
  for (int i = 0; i < 3; ++i)
    for (int r = i + 1; r < 4; ++r)
      for (int j = 0; j < 3; ++j) x[r][j] -= x[i][j] * at(r, i);
  for (int j = 0; j < 3; ++j) {
    V4d t = zero;
    for (int k = 0; k < 4; ++k) t += at(4, k) * x[k][j];
    x[4][j] -= t;
  }
  for (int i = 0; i < 5; ++i) {
    const V4d d = at(i, i);
    const V4i usable = lsf_math::detail::abs(d) > std::numeric_limits<double>::min();
    for (int j = 0; j < 3; ++j) x[i][j] = select(usable, x[i][j] / d, zero);
  }
  for (int i = 3; i >= 0; --i) {
    for (int j = 0; j < 3; ++j) {
      V4d t = zero;
      for (int r = i + 1; r < 5; ++r) t += at(r, i) * x[r][j];
      x[i][j] -= t;
    }
  }
  for (int k = 4; k >= 0; --k)
    if (perm[k] != k)
      for (int j = 0; j < 3; ++j) std::swap(x[k][j], x[perm[k]][j]);
  // Refused: a negative pivot, or a tiny one (rank-deficient linear part); then all_finite.
  V4d min_pivot = at(0, 0), max_pivot = at(0, 0);
  for (int i = 1; i < 5; ++i)
    min_pivot = min4(min_pivot, at(i, i)), max_pivot = max4(max_pivot, at(i, i));
  V4d finite = zero;
  for (int k = 0; k < 5; ++k) {
    for (int j = 0; j < 3; ++j) c[k][j] = x[k][j];
    finite += (x[k][0] - x[k][0]) + (x[k][1] - x[k][1]) + (x[k][2] - x[k][2]);
  }
  valid = positive & ~(min_pivot <= 1e-14 * max_pivot) & (finite == 0);
  return true;
}

// The guard's normal and flat flag of each lane's smooth vertex (FitBatch::normal): the
// NormalSum of its ring's faces, from spoke 0 counter-clockwise as sector_normal walks it,
// every lane at once with NormalSum::add's operations in its order (so bit for bit the
// same), finished lane by lane by NormalSum::normal.
[[gnu::always_inline]] inline void ring_normals(const FitBatch& b, std::size_t n) {
  using lsf_math::detail::select;
  const V4d zero = {0, 0, 0, 0};
  const double inf = std::numeric_limits<double>::infinity();
  V4d ax = zero, ay = zero, az = zero, rx = zero, ry = zero, rz = zero;
  V4d qx = zero, qy = zero, qz = zero;
  V4d fx = zero, fy = zero, fz = zero, shortest = {inf, inf, inf, inf}, longest = zero;
  V4i flat = {-1, -1, -1, -1};
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t j = i + 1 == n ? 0 : i + 1;
    const V4d e1x = load4(b.x[i]), e1y = load4(b.y[i]), e1z = load4(b.z[i]);
    const V4d e2x = load4(b.x[j]), e2y = load4(b.y[j]), e2z = load4(b.z[j]);
    const V4d nx = e1y * e2z - e1z * e2y, ny = e1z * e2x - e1x * e2z, nz = e1x * e2y - e1y * e2x;
    const V4d l1 = e1x * e1x + e1y * e1y + e1z * e1z, l2 = e2x * e2x + e2y * e2y + e2z * e2z;
    const V4d ff = fx * fx + fy * fy + fz * fz;
    const V4i is_first = ff == 0;
    const V4d cx = fy * nz - fz * ny, cy = fz * nx - fx * nz, cz = fx * ny - fy * nx;
    const V4d cc = cx * cx + cy * cy + cz * cz, nn = nx * nx + ny * ny + nz * nz;
    const V4d fn = fx * nx + fy * ny + fz * nz;
    const V4i still_flat = (cc <= (kFlatSine * kFlatSine) * (ff * nn)) & (fn > 0);
    flat = (is_first & flat) | (~is_first & flat & still_flat);
    fx = select(is_first, nx, fx), fy = select(is_first, ny, fy), fz = select(is_first, nz, fz);
    rx += nx, ry += ny, rz += nz;
    const V4d len = lsf_math::sqrt(nn);
    qx += len * nx, qy += len * ny, qz += len * nz;
    const V4d l12 = l1 * l2;
    const V4i positive = l12 > 0;
    const V4d w = 1.0 / lsf_math::sqrt(l12);
    ax = select(positive, ax + nx * w, ax), ay = select(positive, ay + ny * w, ay);
    az = select(positive, az + nz * w, az);
    shortest = min4(shortest, min4(l1, l2)), longest = max4(longest, max4(l1, l2));
  }
  for (int l = 0; l < b.lanes; ++l) {
    if (b.record[l] == nullptr) continue;
    NormalSum sum;
    sum.angle_sum = Vec3(ax[l], ay[l], az[l]), sum.area_sum = Vec3(rx[l], ry[l], rz[l]);
    sum.area2_sum = Vec3(qx[l], qy[l], qz[l]), sum.square_areas = true;
    sum.first = Vec3(fx[l], fy[l], fz[l]);
    sum.shortest = shortest[l], sum.longest = longest[l], sum.flat = flat[l] != 0;
    b.record[l]->normal = sum.normal();
    b.record[l]->flat = sum.flat && dot(sum.first, sum.first) > 0;
    b.record[l]->spokes = sum.spoke_flags();
  }
}

// The kernel, compiled once per instruction set below: n points per lane, a closed ring
// (angles scaled to 2 pi) or an open crease sector (scaled to pi). Lanes from b.lanes to
// kLanes must hold some valid sample (a copy of lane 0).
// kN > 0: compiled for n = kN (the loops unroll fully); 0: any n.
template <std::size_t kN>
[[gnu::always_inline]] inline void fit_batch_body(const FitBatch& b, std::size_t n_any,
                                                  bool closed) {
  const std::size_t n = kN > 0 ? kN : n_any;
  using lsf_math::detail::select;
  // ring_parameters(closed, 2 pi) or (open, pi): gap angles, their sum, the polar angles.
  const std::size_t gaps = closed ? n : n - 1;
  V4d theta[kMaxBatchValence];
  V4d angle_sum = {0, 0, 0, 0};
  for (std::size_t i = 0; i < gaps; ++i) {
    const std::size_t j = i + 1 == n ? 0 : i + 1;
    const V4d ax = load4(b.x[i]), ay = load4(b.y[i]), az = load4(b.z[i]);
    const V4d bx = load4(b.x[j]), by = load4(b.y[j]), bz = load4(b.z[j]);
    const V4d cx = ay * bz - az * by, cy = az * bx - ax * bz, cz = ax * by - ay * bx;
    const V4d cross_len = lsf_math::sqrt(cx * cx + cy * cy + cz * cz);
    theta[i] = lsf_math::atan2(cross_len, ax * bx + ay * by + az * bz);
  }
  for (std::size_t i = 0; i < gaps; ++i) angle_sum += theta[i];
  const V4d one = {1, 1, 1, 1};
  const double total = closed ? 2.0 * std::numbers::pi : std::numbers::pi;
  const V4d scale = select(angle_sum > 0, total / angle_sum, one);
  V4d u[kMaxBatchValence], v[kMaxBatchValence], r[kMaxBatchValence];
  V4d phi = {0, 0, 0, 0};
  for (std::size_t i = 0; i < n; ++i) {
    const V4d px = load4(b.x[i]), py = load4(b.y[i]), pz = load4(b.z[i]);
    const V4d radius = lsf_math::sqrt(px * px + py * py + pz * pz);
    // The first point's angle is 0, whose sincos is exactly (+0, 1).
    V4d sin_phi = {0, 0, 0, 0}, cos_phi = {1, 1, 1, 1};
    if (i > 0) lsf_math::sincos(phi, sin_phi, cos_phi);
    u[i] = radius * cos_phi, v[i] = radius * sin_phi, r[i] = radius;
    if (i < gaps) phi += scale * theta[i];
  }

  // normal_equations: S^T S in three groups of four moments, S^T q by coordinate.
  V4d sum[12], radii[1];
  pair_sums<4>(n, *reinterpret_cast<V4d(*)[4]>(sum + 0), [&](std::size_t i, V4d(&t)[4]) {
    const V4d a = u[i], c = v[i], a2 = a * a;
    t[0] = a2, t[1] = a * c, t[2] = c * c, t[3] = a2 * a;
  });
  pair_sums<4>(n, *reinterpret_cast<V4d(*)[4]>(sum + 4), [&](std::size_t i, V4d(&t)[4]) {
    const V4d a = u[i], c = v[i], a2 = a * a, ac = a * c, c2 = c * c;
    t[0] = a2 * c, t[1] = a * c2, t[2] = c2 * c, t[3] = a2 * a2;
    (void)ac;
  });
  pair_sums<4>(n, *reinterpret_cast<V4d(*)[4]>(sum + 8), [&](std::size_t i, V4d(&t)[4]) {
    const V4d a = u[i], c = v[i], a2 = a * a, ac = a * c, c2 = c * c;
    t[0] = a2 * ac, t[1] = a2 * c2, t[2] = ac * c2, t[3] = c2 * c2;
  });
  pair_sums<1>(n, radii, [&](std::size_t i, V4d(&t)[1]) { t[0] = r[i]; });
  constexpr double kScale[5] = {1, 1, 0.5, 1, 0.5};  // rows u, v, u^2/2, uv, v^2/2
  V4d rhs[5][3];
  for (int d = 0; d < 3; ++d) {
    const double(*w)[kLanes] = d == 0 ? b.x : d == 1 ? b.y : b.z;
    V4d q[5];
    pair_sums<5>(n, q, [&](std::size_t i, V4d(&t)[5]) {
      const V4d a = u[i], c = v[i], p = load4(w[i]);
      t[0] = p * a, t[1] = p * c, t[2] = p * (a * a), t[3] = p * (a * c), t[4] = p * (c * c);
    });
    for (int k = 0; k < 5; ++k) rhs[k][d] = kScale[k] * q[k];
  }

  // solve_fit and fast_solve (mu = 1e-9), every lane at once.
  const V4d mean_radius = radii[0] / static_cast<double>(n);
  const V4d h2 = mean_radius * mean_radius;
  const V4d damping = 1e-9 * (h2 * h2);
  V4d a00 = sum[0], a10 = sum[1], a20 = 0.5 * sum[3], a30 = sum[4], a40 = 0.5 * sum[5];
  V4d a11 = sum[2], a21 = 0.5 * sum[4], a31 = sum[5], a41 = 0.5 * sum[6];
  const V4d n22 = 0.25 * sum[7], n33 = sum[9], n44 = 0.25 * sum[11];
  V4d a22 = n22 + damping, a32 = 0.5 * sum[8], a42 = 0.25 * sum[9];
  V4d a33 = n33 + damping, a43 = 0.5 * sum[10];
  V4d a44 = n44 + damping;
  const V4d min_quadratic = min4(n22, min4(n33, n44));
  const V4d min_diag = min4(min4(a00, a11), min_quadratic);
  const V4d max_diag = max4(max4(a00, a11), max4(a22, max4(a33, a44)));
  const V4d diag_product = a00 * a11 * n22 * n33 * n44;
  // (solve_fit tries the fast path from five points on.)
  V4i certified = (damping <= 1e-7 * min_quadratic) & (min_diag >= 1e-8 * max_diag) &
                  (diag_product >= 1e-250) & (diag_product <= 1e250) &
                  (n >= 5 ? V4i{-1, -1, -1, -1} : V4i{0, 0, 0, 0});
  V4d b0[3], b1[3], b2[3], b3[3], b4[3];  // the right-hand sides, eliminated in place
  for (int d = 0; d < 3; ++d)
    b0[d] = rhs[0][d], b1[d] = rhs[1][d], b2[d] = rhs[2][d], b3[d] = rhs[3][d], b4[d] = rhs[4][d];
  auto eliminate = [](V4d(&to)[3], V4d l, const V4d(&from)[3]) {
    for (int d = 0; d < 3; ++d) to[d] -= l * from[d];
  };
  const V4d d0 = a00;
  const V4d i0 = 1.0 / d0;
  const V4d l10 = a10 * i0, l20 = a20 * i0, l30 = a30 * i0, l40 = a40 * i0;
  a11 -= l10 * a10, a21 -= l20 * a10, a31 -= l30 * a10, a41 -= l40 * a10;
  a22 -= l20 * a20, a32 -= l30 * a20, a42 -= l40 * a20;
  a33 -= l30 * a30, a43 -= l40 * a30;
  a44 -= l40 * a40;
  eliminate(b1, l10, b0), eliminate(b2, l20, b0), eliminate(b3, l30, b0), eliminate(b4, l40, b0);
  const V4d d1 = a11;
  const V4d i1 = 1.0 / d1;
  const V4d l21 = a21 * i1, l31 = a31 * i1, l41 = a41 * i1;
  a22 -= l21 * a21, a32 -= l31 * a21, a42 -= l41 * a21;
  a33 -= l31 * a31, a43 -= l41 * a31;
  a44 -= l41 * a41;
  eliminate(b2, l21, b1), eliminate(b3, l31, b1), eliminate(b4, l41, b1);
  const V4d d2 = a22;
  const V4d i2 = 1.0 / d2;
  const V4d l32 = a32 * i2, l42 = a42 * i2;
  a33 -= l32 * a32, a43 -= l42 * a32;
  a44 -= l42 * a42;
  eliminate(b3, l32, b2), eliminate(b4, l42, b2);
  const V4d d3 = a33;
  const V4d i3 = 1.0 / d3;
  const V4d l43 = a43 * i3;
  a44 -= l43 * a43;
  eliminate(b4, l43, b3);
  const V4d d4 = a44;
  const V4d i4 = 1.0 / d4;
  certified &= (d0 > 0) & (d1 > 0) & (d2 > 0) & (d3 > 0) & (d4 > 0) &
               (d0 * d1 * d2 * d3 * d4 >= kDetFloor * diag_product);
  V4d c[5][3];
  for (int d = 0; d < 3; ++d) {
    c[4][d] = i4 * b4[d];
    c[3][d] = i3 * b3[d] - l43 * c[4][d];
    c[2][d] = i2 * b2[d] - l32 * c[3][d] - l42 * c[4][d];
    c[1][d] = i1 * b1[d] - l21 * c[2][d] - l31 * c[3][d] - l41 * c[4][d];
    c[0][d] = i0 * b0[d] - l10 * c[1][d] - l20 * c[2][d] - l30 * c[3][d] - l40 * c[4][d];
  }
  // all_finite, lane by lane.
  V4d zero = {0, 0, 0, 0};
  for (const auto& row : c) zero += (row[0] - row[0]) + (row[1] - row[1]) + (row[2] - row[2]);
  V4i valid = certified & (zero == 0);
  if (!(certified[0] && certified[1] && certified[2] && certified[3])) {
    // Below five points every lane takes the general path (crease sectors of four points
    // are common), else only the rare lane the certificate refused.
    if (n >= 5 || !general_solve_small(sum, rhs, damping, c, valid)) {
      for (int l = 0; l < kLanes; ++l)
        if (!certified[l]) valid[l] = solve_lane(sum, rhs, radii[0], n, l, c) ? -1 : 0;
    }
  }

  // half_points: s(u/2, v/2) - V + V, or the chord midpoint where the fit is not valid.
  V4d h[5][3];
  for (int d = 0; d < 3; ++d) {
    h[0][d] = 0.5 * c[0][d], h[1][d] = 0.5 * c[1][d], h[2][d] = 0.125 * c[2][d];
    h[3][d] = 0.25 * c[3][d], h[4][d] = 0.125 * c[4][d];
  }
  if (closed) ring_normals(b, n);

  // Written straight to their destinations: every point of a ring, the inner points of a
  // sector (its two ends are the sharp spokes, whose edges take the curve rule).
  const V4d origin[3] = {load4(b.ox), load4(b.oy), load4(b.oz)};
  for (std::size_t i = closed ? 0 : 1; i < (closed ? n : n - 1); ++i) {
    const V4d a = u[i], e = v[i], a2 = a * a, ae = a * e, e2 = e * e;
    const V4d chord[3] = {load4(b.x[i]), load4(b.y[i]), load4(b.z[i])};
    V4d q[3];
    for (int d = 0; d < 3; ++d) {
      const V4d fit = a * h[0][d] + e * h[1][d] + a2 * h[2][d] + ae * h[3][d] + e2 * h[4][d];
      q[d] = origin[d] + select(valid, fit, 0.5 * chord[d]);
    }
    for (int l = 0; l < b.lanes; ++l) *b.dest[i][l] = Vec3(q[0][l], q[1][l], q[2][l]);
  }
}

// The sizes unrolled, written once; each kernel below inlines it (flatten) for its target.
inline void fit_batch_sized(const FitBatch& b, std::size_t n, bool closed) {
  switch (n) {  // the common sizes: rings of 5-7, sectors of 3-5
    case 3:
      return fit_batch_body<3>(b, n, closed);
    case 4:
      return fit_batch_body<4>(b, n, closed);
    case 5:
      return fit_batch_body<5>(b, n, closed);
    case 6:
      return fit_batch_body<6>(b, n, closed);
    case 7:
      return fit_batch_body<7>(b, n, closed);
    default:
      return fit_batch_body<0>(b, n, closed);
  }
}

[[gnu::flatten]] void fit_batch_baseline(const FitBatch& b, std::size_t n, bool closed) {
  fit_batch_sized(b, n, closed);
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
// The same kernel on AVX2's four-lane registers (AVX2 only: no FMA, which would change the
// rounding). Chosen at run time, so the binary still runs on any x86-64.
[[gnu::target("avx2"), gnu::flatten]] void fit_batch_avx2(const FitBatch& b, std::size_t n,
                                                          bool closed) {
  fit_batch_sized(b, n, closed);
}
bool cpu_has_avx2() {
  return __builtin_cpu_supports("avx2");
}
#else
FitBatchFn fit_batch_avx2 = nullptr;
bool cpu_has_avx2() {
  return false;
}
#endif

FitBatchFn fit_batch_kernel(LsfKernel choice) {
  static const bool avx2 = cpu_has_avx2();
  return avx2 && choice == LsfKernel::Auto ? fit_batch_avx2 : fit_batch_baseline;
}

}  // namespace

Batches::Batches(LsfKernel choice) : kernel(fit_batch_kernel(choice)) {}

void Batches::flush() {
  for (bool closed : {true, false}) {
    auto& batches = closed ? ring : sector;
    for (std::size_t n = 0; n < batches.size(); ++n) {
      FitBatch& b = batches[n];
      if (b.lanes == 0) continue;
      for (int l = b.lanes; l < kLanes; ++l) {
        b.ox[l] = b.ox[0], b.oy[l] = b.oy[0], b.oz[l] = b.oz[0];
        for (std::size_t i = 0; i < n; ++i)
          b.x[i][l] = b.x[i][0], b.y[i][l] = b.y[i][0], b.z[i][l] = b.z[i][0];
      }
      fit(b, n, closed);
    }
  }
}

// Walks v's ring into the batch of its valence when v is smooth or a dart (whose whole ring
// is fitted too) with a closed ring of kMinBatchValence..kMaxBatchValence points, and fits
// the batch when it is full; false, with nothing changed, for every other vertex. A dart's
// sharp spoke gets an estimate too: harmless, the sharp edge's point is the curve rule's.
bool batch_smooth_vertex(const Mesh& m, VertexId v, const EstimateSlots& slots, Batches& batches,
                         GuardVertex* record) {
  const HalfedgeId start = m.halfedge(v);
  if (!start.valid()) return false;
  // The spokes first (a chain of dependent loads), then their far ends' positions (loads
  // independent of each other), straight into the batch's lane.
  // twin(spoke[i + 1]) = prev(spoke[i]), and the ring is closed: twin(spoke[i]) is
  // prev_spoke[i - 1] (cyclically), with no load.
  HalfedgeId spoke[kMaxBatchValence], prev_spoke[kMaxBatchValence];
  std::size_t n = 0;
  HalfedgeId h = start;
  do {
    if (n == kMaxBatchValence) return false;
    spoke[n] = h;
    prev_spoke[n] = Mesh::prev(h);
    h = m.twin(prev_spoke[n++]);  // ccw_rotated
  } while (h.valid() && h != start);
  if (!h.valid() || n < kMinBatchValence) return false;
  FitBatch& b = batches.ring[n];
  const int l = b.lanes++;
  const Vec3 p = m.position(v);
  b.ox[l] = p.x, b.oy[l] = p.y, b.oz[l] = p.z;
  HalfedgeId twin = prev_spoke[n - 1];
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 d = m.position(m.from(twin)) - p;  // to(spoke[i])
    b.x[i][l] = d.x, b.y[i][l] = d.y, b.z[i][l] = d.z;
    b.dest[i][l] = slots.at(m.edge(spoke[i]), spoke[i].idx < twin.idx);
    twin = prev_spoke[i];
  }
  // The guard's normal of a smooth vertex, from these offsets, in sector_normal's order (from
  // m.halfedge(v), counter-clockwise), by the kernel (ring_normals).
  b.record[l] = record;
  if (b.lanes == kLanes) batches.fit(b, n, true);
  return true;
}

// A crease vertex's sectors, as for_each_sector_fit cuts them (the ring from its first
// sharp spoke, closed by a copy of that spoke's point; on a boundary the fan from its
// boundary spoke, closed by the far end of the incoming boundary edge; each sector from one
// sharp spoke to the next, both included), into the sector batches by size; false, with
// nothing changed, when a ring or sector is too large (the caller fits the vertex alone).
bool batch_crease_vertex(const Mesh& m, const Features& f, VertexId v, const EstimateSlots& slots,
                         Batches& batches) {
  constexpr std::size_t kMaxRing = 2 * kMaxBatchValence;
  const HalfedgeId start = m.halfedge(v);
  if (!start.valid()) return false;
  HalfedgeId spoke[kMaxRing], prev_spoke[kMaxRing];
  std::size_t n = 0;
  HalfedgeId h = start;
  do {
    if (n == kMaxRing) return false;
    spoke[n] = h;
    prev_spoke[n] = Mesh::prev(h);
    h = m.twin(prev_spoke[n++]);
  } while (h.valid() && h != start);
  const bool closed = h.valid();
  // The ring in for_each_sector_fit's order: point k is spoke (first + k) mod n, point n
  // closes it. Its sharp points cut it into sectors.
  bool sharp[kMaxRing + 1];
  for (std::size_t i = 0; i < n; ++i) sharp[i] = f.is_sharp(m.edge(spoke[i]));
  std::size_t first = 0;
  if (closed) {
    while (first < n && !sharp[first]) ++first;
    if (first == n) return false;
  }
  auto at = [&](std::size_t k) { return k == n ? (closed ? first : n) : (first + k) % n; };
  std::size_t cut[kMaxRing + 1], cuts = 0;  // ring points where sectors begin and end
  for (std::size_t k = 0; k <= n; ++k) {
    if (k == 0 || k == n || sharp[at(k)]) cut[cuts++] = k;
    if (cuts >= 2 && cut[cuts - 1] - cut[cuts - 2] + 1 > kMaxBatchValence) return false;
  }
  const Vec3 p = m.position(v);
  // Ring point k: its offset from p and, for a spoke with a twin, where its estimate goes.
  auto offset = [&](std::size_t k) {
    const std::size_t j = at(k);
    if (j == n) return m.position(m.from(prev_spoke[n - 1])) - p;  // closes an open fan
    if (!closed && j == 0) return m.position(m.to(spoke[0])) - p;  // the boundary spoke
    return m.position(m.from(prev_spoke[j == 0 ? n - 1 : j - 1])) - p;
  };
  for (std::size_t c = 1; c < cuts; ++c) {
    const std::size_t begin = cut[c - 1], size = cut[c] - begin + 1;
    if (size < 3) continue;  // no inner point: nothing to estimate
    FitBatch& b = batches.sector[size];
    const int l = b.lanes++;
    b.ox[l] = p.x, b.oy[l] = p.y, b.oz[l] = p.z;
    for (std::size_t i = 0; i < size; ++i) {
      const Vec3 d = offset(begin + i);
      b.x[i][l] = d.x, b.y[i][l] = d.y, b.z[i][l] = d.z;
      if (i == 0 || i + 1 == size) continue;
      // An inner point is a smooth spoke j >= 1 of an open fan or any of a closed ring: its
      // twin is prev(spoke[j - 1]).
      const std::size_t j = at(begin + i);
      const HalfedgeId twin = prev_spoke[j == 0 ? n - 1 : j - 1];
      b.dest[i][l] = slots.at(m.edge(spoke[j]), spoke[j].idx < twin.idx);
    }
    if (b.lanes == kLanes) batches.fit(b, size, false);
  }
  return true;
}

}  // namespace stlrefine::lsf
