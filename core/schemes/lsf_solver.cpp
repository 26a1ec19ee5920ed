// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/lsf_solver.h"

#include <algorithm>
#include <cmath>
#include <cstring>

// -Wpsabi (32-byte vectors in internal signatures) is silenced by lsf_fast_math.h for its
// includers.

namespace stlrefine {
namespace lsf {
namespace {

// Relative singular value of the scaled design matrix below which a direction counts as
// undetermined. Well-spread rings sit above 1e-1; a perturbed crease strip near 1e-5.
constexpr double kSingularCutoff = 1e-3;
// The damping used for such samples: far above their tiny singular values squared, so the
// undetermined second-order combination is set to its minimum norm, as spec 5 gap 1 does
// for valence < 5, and small enough that the determined terms are not biased (~1e-6).
constexpr double kIllConditionedMu = 1e-6;

// The general path's 5x5 factorisation: Eigen 3.4's LDLT written out for 5x5 (lower
// storage, diagonal pivoting on the largest remaining |d|, the same order of every sum and
// update), so its decisions (success, sign, smallest pivot) are Eigen::LDLT's. Eigen's
// general-size machinery cost more than the arithmetic. Low-valence fits under the damping
// of spec 5 gap 1 (mu = 1e-9) are so ill-conditioned that a last-bit change of their input
// grows to ~1e-8 of the model size one level later: the fast path below leaves them here.

struct Ldlt5 {
  Mat5 a{};                   // column-major: L strictly below the diagonal, D on it
  std::array<int, 5> perm{};  // transposition k <-> perm[k] at step k
  bool success = true;        // Eigen's info() == Success
  bool positive = true;       // Eigen's isPositive(): no negative pivot

  // Element (row r, column c); columns are contiguous, so the per-column divisions and
  // updates below vectorise (each element still sees the same operations in the same order).
  double& at(int r, int c) { return a[c][r]; }
  double at(int r, int c) const { return a[c][r]; }

  explicit Ldlt5(const Mat5& m) : a(m) {
    bool found_zero_pivot = false;
    // Unrolled, so every inner loop below has fixed bounds.
#pragma GCC unroll 5
    for (int k = 0; k < 5; ++k) {
      int p = k;
      double biggest = std::abs(at(k, k));
      for (int i = k + 1; i < 5; ++i) {
        if (std::abs(at(i, i)) > biggest) biggest = std::abs(at(i, i)), p = i;
      }
      perm[k] = p;
      if (p != k) {
        for (int j = 0; j < k; ++j) std::swap(at(k, j), at(p, j));
        for (int i = p + 1; i < 5; ++i) std::swap(at(i, k), at(i, p));
        std::swap(at(k, k), at(p, p));
        for (int i = k + 1; i < p; ++i) std::swap(at(i, k), at(p, i));
      }
      if (k > 0) {
        std::array<double, 5> temp;
        for (int j = 0; j < k; ++j) temp[j] = at(j, j) * at(k, j);
        double s = at(k, 0) * temp[0];
        for (int j = 1; j < k; ++j) s += at(k, j) * temp[j];
        at(k, k) -= s;
        for (int i = k + 1; i < 5; ++i) {
          double c = 0;
          for (int j = 0; j < k; ++j) c += at(i, j) * temp[j];
          at(i, k) -= c;
        }
      }
      const double akk = at(k, k);
      const bool pivot_valid = std::abs(akk) > 0;
      if (k == 0 && !pivot_valid) {
        // A zero diagonal: Eigen stops here (sign "zero", positive semi-definite).
        for (int j = 0; j < 5; ++j) perm[j] = j;
        for (int j = 0; j < 5; ++j)
          for (int i = j + 1; i < 5; ++i) success = success && at(i, j) == 0;
        return;
      }
      if (pivot_valid) {
        for (int i = k + 1; i < 5; ++i) at(i, k) /= akk;
      } else {
        for (int i = k + 1; i < 5; ++i) success = success && at(i, k) == 0;
      }
      if (found_zero_pivot && pivot_valid)
        success = false;
      else if (!pivot_valid)
        found_zero_pivot = true;
      if (akk < 0) positive = false;
    }
  }

  double min_pivot() const {
    double m = at(0, 0);
    for (int i = 1; i < 5; ++i) m = std::min(m, at(i, i));
    return m;
  }
  double max_pivot() const {
    double m = at(0, 0);
    for (int i = 1; i < 5; ++i) m = std::max(m, at(i, i));
    return m;
  }

  // Solves for three right-hand sides (x, y, z), in place, as Eigen's solve() does.
  void solve(std::array<std::array<double, 3>, 5>& x) const {
    for (int k = 0; k < 5; ++k)
      if (perm[k] != k) std::swap(x[k], x[perm[k]]);
    // L y = P b: rows 0-3 column by column (Eigen's triangular panel), row 4 as one sum.
    for (int i = 0; i < 3; ++i)
      for (int r = i + 1; r < 4; ++r)
        for (int j = 0; j < 3; ++j) x[r][j] -= x[i][j] * at(r, i);
    for (int j = 0; j < 3; ++j) {
      double c = 0;
      for (int k = 0; k < 4; ++k) c += at(4, k) * x[k][j];
      x[4][j] -= c;
    }
    for (int i = 0; i < 5; ++i) {
      const double d = at(i, i);
      for (int j = 0; j < 3; ++j)
        x[i][j] = std::abs(d) > std::numeric_limits<double>::min() ? x[i][j] / d : 0.0;
    }
    // L^T x = D^-1 y, from the last row up, each row as one sum.
    for (int i = 3; i >= 0; --i) {
      for (int j = 0; j < 3; ++j) {
        double b = 0;
        for (int r = i + 1; r < 5; ++r) b += at(r, i) * x[r][j];
        x[i][j] -= b;
      }
    }
    for (int k = 4; k >= 0; --k)
      if (perm[k] != k) std::swap(x[k], x[perm[k]]);
  }
};

// True when the unit-diagonal (Jacobi-scaled) normal matrix has an eigenvalue below the
// squared cut-off, i.e. a relative singular value of the scaled design matrix below
// kSingularCutoff: a test independent of units and parameter scale. Decided exactly by
// Sylvester's criterion: unit - cutoff^2 I is positive definite iff every pivot of its
// unpivoted LDL^T is positive. (The smallest pivot of a pivoted factorisation, used before,
// depends on the pivot order, which the all-ones diagonal leaves to rounding noise: a
// last-bit change of the sample flipped the decision on borderline crease sectors.)
bool poorly_conditioned(const Mat5& normal) {
  std::array<double, 5> inv_sqrt;
  for (int i = 0; i < 5; ++i) {
    if (!(normal[i][i] > 0)) return true;
    inv_sqrt[i] = 1.0 / std::sqrt(normal[i][i]);
  }
  // Lower part, [col][row]; right-looking elimination.
  Mat5 a;
  for (int i = 0; i < 5; ++i)
    for (int j = 0; j <= i; ++j) a[j][i] = (inv_sqrt[i] * normal[j][i]) * inv_sqrt[j];
  for (int k = 0; k < 5; ++k) a[k][k] -= kSingularCutoff * kSingularCutoff;
  for (int j = 0; j < 5; ++j) {
    const double d = a[j][j];
    if (!(d > 0)) return true;  // NaN too
    for (int i = j + 1; i < 5; ++i) {
      const double l = a[j][i] / d;
      for (int k = i; k < 5; ++k) a[i][k] -= l * a[j][k];
    }
  }
  return false;
}

bool all_finite(const Coefficients& c) {
  // x - x is 0 for finite x and NaN for inf and NaN; NaN fails every comparison.
  double zero = 0;
  for (const Vec3& row : c) zero += (row.x - row.x) + (row.y - row.y) + (row.z - row.z);
  return zero == 0;
}

// The damped fit, fast path. Almost every sample is well spread; for those the general
// path's two pivoted factorisations (conditioning test, damped solve) are replaced by one
// unpivoted LDL^T of the damped matrix M = N + damping diag(0,0,1,1,1), whose pivots d_k
// also prove that the general path would take the same decisions:
//  * Jacobi-scale N to unit diagonal (N_s = S N S) and M alike (M_s = S M S). Then
//    det M_s = prod d_k / prod N_kk, trace M_s = 5 + damping sum_{k>=2} 1/N_kk, and by the
//    AM-GM inequality on its eigenvalues lambda_min(M_s) >= det M_s / (trace M_s / 4)^4.
//    By Weyl, lambda_min(N_s) >= lambda_min(M_s) - damping max_{k>=2} 1/N_kk.
//    With damping <= 1e-7 min_{k>=2} N_kk and det M_s >= kDetFloor that gives
//    lambda_min(N_s) >= kDetFloor / ((5 + 3e-7) / 4)^4 - 1e-7 > 2e-6.
//  * lambda_min(N_s) > 2e-6, twice kSingularCutoff^2, means the conditioning test passes:
//    mu stays as it is here.
//  * The general path refuses a fit whose smallest pivot of M is below 1e-14 of its largest.
//    Every pivot of a symmetric-pivoted LDL^T of an SPD matrix is a diagonal entry of a
//    Schur complement, so its pivots lie in [lambda_min(M), max M_kk]; lambda_min(M) >=
//    lambda_min(N) >= lambda_min(N_s) min N_kk > 2e-6 min N_kk, so min N_kk >= 1e-8 max M_kk
//    means it accepts (again a factor of two of margin).
// The margins are far above the rounding of either path, so only the last bits of the
// solution differ (the elimination order does). Otherwise, and below five points, and when
// the products leave the comfortable range of doubles, the general path runs.
// (kDetFloor: lsf_solver.h.)

bool fast_solve(const NormalEquations& e, double damping, Coefficients& c) {
  const double* s = e.s;
  // Lower part of M, column by column.
  double a00 = s[0], a10 = s[1], a20 = 0.5 * s[3], a30 = s[4], a40 = 0.5 * s[5];
  double a11 = s[2], a21 = 0.5 * s[4], a31 = s[5], a41 = 0.5 * s[6];
  const double n22 = 0.25 * s[7], n33 = s[9], n44 = 0.25 * s[11];
  double a22 = n22 + damping, a32 = 0.5 * s[8], a42 = 0.25 * s[9];
  double a33 = n33 + damping, a43 = 0.5 * s[10];
  double a44 = n44 + damping;
  const double min_quadratic = std::min(n22, std::min(n33, n44));
  const double min_diag = std::min(std::min(a00, a11), min_quadratic);
  const double max_diag = std::max(std::max(a00, a11), std::max(a22, std::max(a33, a44)));
  const double diag_product = a00 * a11 * n22 * n33 * n44;
  if (!(damping <= 1e-7 * min_quadratic) || !(min_diag >= 1e-8 * max_diag) ||
      !(diag_product >= 1e-250 && diag_product <= 1e250))
    return false;
  Vec3 b0 = e.q[0], b1 = e.q[1], b2 = e.q[2], b3 = e.q[3], b4 = e.q[4];
  // Right-looking elimination; the forward substitution of b goes along.
  const double d0 = a00;
  const double i0 = 1.0 / d0;
  const double l10 = a10 * i0, l20 = a20 * i0, l30 = a30 * i0, l40 = a40 * i0;
  a11 -= l10 * a10, a21 -= l20 * a10, a31 -= l30 * a10, a41 -= l40 * a10;
  a22 -= l20 * a20, a32 -= l30 * a20, a42 -= l40 * a20;
  a33 -= l30 * a30, a43 -= l40 * a30;
  a44 -= l40 * a40;
  b1 -= l10 * b0, b2 -= l20 * b0, b3 -= l30 * b0, b4 -= l40 * b0;
  const double d1 = a11;
  const double i1 = 1.0 / d1;
  const double l21 = a21 * i1, l31 = a31 * i1, l41 = a41 * i1;
  a22 -= l21 * a21, a32 -= l31 * a21, a42 -= l41 * a21;
  a33 -= l31 * a31, a43 -= l41 * a31;
  a44 -= l41 * a41;
  b2 -= l21 * b1, b3 -= l31 * b1, b4 -= l41 * b1;
  const double d2 = a22;
  const double i2 = 1.0 / d2;
  const double l32 = a32 * i2, l42 = a42 * i2;
  a33 -= l32 * a32, a43 -= l42 * a32;
  a44 -= l42 * a42;
  b3 -= l32 * b2, b4 -= l42 * b2;
  const double d3 = a33;
  const double i3 = 1.0 / d3;
  const double l43 = a43 * i3;
  a44 -= l43 * a43;
  b4 -= l43 * b3;
  const double d4 = a44;
  const double i4 = 1.0 / d4;
  // Positive pivots (NaN fails too) whose product clears the floor: the certificate.
  if (!(d0 > 0 && d1 > 0 && d2 > 0 && d3 > 0 && d4 > 0) ||
      !(d0 * d1 * d2 * d3 * d4 >= kDetFloor * diag_product))
    return false;
  // Back substitution through D and L^T.
  c[4] = i4 * b4;
  c[3] = i3 * b3 - l43 * c[4];
  c[2] = i2 * b2 - l32 * c[3] - l42 * c[4];
  c[1] = i1 * b1 - l21 * c[2] - l31 * c[3] - l41 * c[4];
  c[0] = i0 * b0 - l10 * c[1] - l20 * c[2] - l30 * c[3] - l40 * c[4];
  return true;
}

// Solves the damped normal equations (spec 5 gap 1); false for a degenerate sample.
bool general_solve(const NormalEquations& e, std::size_t count, double mu, double h2,
                   Coefficients& c);

}  // namespace

bool solve_fit(const NormalEquations& e, std::size_t count, double mu, Coefficients& c) {
  if (count == 0) return false;
  const double mean_radius = e.radius_sum / static_cast<double>(count);
  const double h2 = mean_radius * mean_radius;
  if (count >= 5 && fast_solve(e, mu * (h2 * h2), c)) return all_finite(c);
  return general_solve(e, count, mu, h2, c);
}

namespace {

// The general path: the conditioning test, then Eigen's pivoted LDLT (Ldlt5).
[[gnu::noinline]] bool general_solve(const NormalEquations& e, std::size_t count, double mu,
                                     double h2, Coefficients& c) {
  Mat5 normal = e.matrix();
  if (count >= 5) {
    // Five or more points can still be nearly degenerate: the side points of a crease
    // vertex on a developable strip lie close to two lines parallel to the crease (a
    // degenerate conic), and the exact least-squares quadric then swings far off the
    // surface (50 mm on a 10 mm cylinder in the fidelity bench). Such samples are damped
    // firmly.
    if (poorly_conditioned(normal)) mu = std::max(mu, kIllConditionedMu);
  }
  // Damp only the second-order terms: below valence 5 S^T S is singular, and the damped
  // solution tends to the interpolating quadric with the smallest curvature terms.
  const double damping = mu * (h2 * h2);
  for (int k = 2; k < 5; ++k) normal[k][k] += damping;
  const Ldlt5 ldlt(normal);
  if (!ldlt.success || !ldlt.positive) return false;
  std::array<std::array<double, 3>, 5> x;
  for (int k = 0; k < 5; ++k) x[k] = {e.q[k].x, e.q[k].y, e.q[k].z};
  ldlt.solve(x);
  // A rank-deficient linear part (collinear sample) shows as a tiny pivot: refuse it.
  if (ldlt.min_pivot() <= 1e-14 * ldlt.max_pivot()) return false;
  for (int k = 0; k < 5; ++k) c[k] = {x[k][0], x[k][1], x[k][2]};
  return all_finite(c);
}

// Welch-Witkin parameters of the sample: angles between consecutive offsets (the last and
// the first too when `closed`) scaled to sum to `total_angle` (0: natural angles), radius
// = distance. Leaves x, y, z zero at index size (the pairs' padding).
void ring_parameters(Sample& s, bool closed, double total_angle) {
  const std::size_t n = s.size;
  if (n == 0) return;
  const std::size_t gaps = closed ? n : n - 1;
  // Padding: gap i joins points i and i+1; the pair loop reads up to point gaps + 1.
  for (std::size_t i = n; i < n + 2; ++i) {
    const std::size_t from = closed ? i - n : n - 1;
    s.x[i] = s.x[from], s.y[i] = s.y[from], s.z[i] = s.z[from];
  }
  for (std::size_t i = 0; i < gaps; i += 2) {
    const V2d ax = load2(s.x + i), ay = load2(s.y + i), az = load2(s.z + i);
    const V2d bx = load2(s.x + i + 1), by = load2(s.y + i + 1), bz = load2(s.z + i + 1);
    const V2d cx = ay * bz - az * by, cy = az * bx - ax * bz, cz = ax * by - ay * bx;
    const V2d cross_len = lsf_math::sqrt(cx * cx + cy * cy + cz * cz);
    store2(s.phi + i, lsf_math::atan2(cross_len, ax * bx + ay * by + az * bz));
  }
  double angle_sum = 0;
  for (std::size_t i = 0; i < gaps; ++i) angle_sum += s.phi[i];
  const double scale = (total_angle > 0 && angle_sum > 0) ? total_angle / angle_sum : 1.0;
  double phi = 0;
  for (std::size_t i = 0; i < n; ++i) {  // gap angles -> polar angles, in place
    const double angle = s.phi[i];       // unset for the last point of an open fan: unused
    s.phi[i] = phi;
    if (i < gaps) phi += scale * angle;
  }
  s.phi[n] = 0;  // the padding lane
  for (std::size_t i = 0; i < n; i += 2) {
    const V2d px = load2(s.x + i), py = load2(s.y + i), pz = load2(s.z + i);
    const V2d radius = lsf_math::sqrt(px * px + py * py + pz * pz);
    V2d sin_phi, cos_phi;
    lsf_math::sincos(load2(s.phi + i), sin_phi, cos_phi);
    store2(s.u + i, radius * cos_phi);
    store2(s.v + i, radius * sin_phi);
    store2(s.r + i, radius);
  }
  // A point at the origin with zero parameters adds nothing to any sum below.
  s.x[n] = s.y[n] = s.z[n] = s.u[n] = s.v[n] = s.r[n] = 0;
}

double sum_lanes(V2d v) {
  return v[0] + v[1];
}

// The normal equations of the sample's fit, two points at a time (each lane sums every
// other point; the padding point adds zeros).
NormalEquations normal_equations(const Sample& s) {
  const std::size_t n = s.size;
  NormalEquations e;  // every field is written below
  // Three passes, so each one's running sums fit in registers.
  V2d m[12] = {}, radius = {0, 0};
  for (std::size_t i = 0; i < n; i += 2) {
    const V2d a = load2(s.u + i), b = load2(s.v + i);
    const V2d a2 = a * a, ab = a * b, b2 = b * b;
    m[0] += a2, m[1] += ab, m[2] += b2;
    m[3] += a2 * a, m[4] += a2 * b, m[5] += a * b2, m[6] += b2 * b;
    m[7] += a2 * a2, m[8] += a2 * ab, m[9] += a2 * b2, m[10] += ab * b2, m[11] += b2 * b2;
    radius += load2(s.r + i);
  }
  for (int k = 0; k < 12; ++k) e.s[k] = sum_lanes(m[k]);
  e.radius_sum = sum_lanes(radius);
  V2d qx[5] = {}, qy[5] = {}, qz[5] = {};
  for (std::size_t i = 0; i < n; i += 2) {
    const V2d a = load2(s.u + i), b = load2(s.v + i);
    const V2d basis[5] = {a, b, a * a, a * b, b * b};
    const V2d wx = load2(s.x + i), wy = load2(s.y + i);
    for (int k = 0; k < 5; ++k) qx[k] += wx * basis[k], qy[k] += wy * basis[k];
  }
  for (std::size_t i = 0; i < n; i += 2) {
    const V2d a = load2(s.u + i), b = load2(s.v + i);
    const V2d basis[5] = {a, b, a * a, a * b, b * b};
    const V2d wz = load2(s.z + i);
    for (int k = 0; k < 5; ++k) qz[k] += wz * basis[k];
  }
  constexpr double kScale[5] = {1, 1, 0.5, 1, 0.5};  // rows u, v, u^2/2, uv, v^2/2
  for (int k = 0; k < 5; ++k)
    e.q[k] = kScale[k] * Vec3(sum_lanes(qx[k]), sum_lanes(qy[k]), sum_lanes(qz[k]));
  return e;
}

}  // namespace

SampleFit fit_sample(Sample& s, bool closed, double total_angle, double mu) {
  SampleFit f;  // c is written when valid
  f.sample = &s;
  ring_parameters(s, closed, total_angle);
  f.valid = solve_fit(normal_equations(s), s.size, mu, f.c);
  return f;
}

// Per-thread samples: the ring being walked, and one sector of it.
Sample& ring_sample() {
  thread_local Sample sample;
  sample.clear();
  sample.reserve(32);
  return sample;
}
Sample& sector_sample() {
  thread_local Sample sample;
  sample.clear();
  sample.reserve(32);
  return sample;
}

}  // namespace lsf

using lsf::Coefficients;
using lsf::normal_equations;
using lsf::ring_parameters;
using lsf::ring_sample;
using lsf::Sample;
using lsf::solve_fit;

void polar_parameters(const Vec3& origin, std::span<const Vec3> points, bool closed,
                      double total_angle, std::span<std::array<double, 2>> params) {
  Sample& s = ring_sample();
  for (const Vec3& p : points) s.push(p - origin);
  ring_parameters(s, closed, total_angle);
  for (std::size_t i = 0; i < points.size(); ++i) params[i] = {s.u[i], s.v[i]};
}

QuadricFit fit_quadric(const Vec3& origin, std::span<const Vec3> points,
                       std::span<const std::array<double, 2>> params, double mu) {
  Sample& s = ring_sample();
  for (const Vec3& p : points) s.push(p - origin);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto [u, v] = params[i];
    s.u[i] = u, s.v[i] = v, s.r[i] = std::sqrt(u * u + v * v);
  }
  s.x[s.size] = s.y[s.size] = s.z[s.size] = s.u[s.size] = s.v[s.size] = s.r[s.size] = 0;
  QuadricFit fit;
  fit.origin = origin;
  Coefficients c;
  if (!solve_fit(normal_equations(s), points.size(), mu, c)) return fit;
  fit.c = c;
  fit.valid = true;
  return fit;
}

}  // namespace stlrefine
