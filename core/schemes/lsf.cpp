// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/lsf.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <numbers>
#include <utility>
#include <vector>

#include "core/parallel.h"
#include "core/schemes/crease_rules.h"
#include "core/schemes/lsf_fast_math.h"

// -Wpsabi (32-byte vectors in internal signatures) is silenced by lsf_fast_math.h for its
// includers.

namespace stlrefine {

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
using Mat5 = std::array<std::array<double, 5>, 5>;  // [col][row]; the lower part is read

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
constexpr double kDetFloor = 6e-6;  // 2.1e-6 * ((5 + 3e-7) / 4)^4 = 5.13e-6, rounded up

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

bool solve_fit(const NormalEquations& e, std::size_t count, double mu, Coefficients& c) {
  if (count == 0) return false;
  const double mean_radius = e.radius_sum / static_cast<double>(count);
  const double h2 = mean_radius * mean_radius;
  if (count >= 5 && fast_solve(e, mu * (h2 * h2), c)) return all_finite(c);
  return general_solve(e, count, mu, h2, c);
}

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

using lsf_math::V2d;

V2d load2(const double* p) {
  V2d v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
void store2(double* p, V2d v) {
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

SampleFit fit_sample(Sample& s, bool closed, double total_angle, double mu = 1e-9) {
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

}  // namespace

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

namespace {

//! Walks v's ring once and fits one quadric per sector (the whole ring for smooth and dart
//! vertices), calling on_sector(fit, ring, begin) for each sector: points begin..begin +
//! fit.sample->size of `ring`. ring.spoke[i] is the outgoing half-edge to ring point i
//! (invalid for the point that closes an open fan), ring.sharp[i] whether it is sharp.
//! Crease sectors are scaled to pi, corners keep natural angles.
template <class OnSector>
void for_each_sector_fit(const Mesh& m, const Features& f, VertexId v, OnSector&& on_sector) {
  const HalfedgeId start = m.halfedge(v);
  if (!start.valid()) return;
  Sample& ring = ring_sample();
  const Vec3 p = m.position(v);
  const VertexKind kind = f.kind(v);
  if (kind == VertexKind::Smooth) {
    // No sharp spoke, and not on a boundary (boundary edges are sharp): a closed ring.
    // Through local pointers: stores to the sample's arrays would otherwise make the compiler
    // reload its fields after each one.
    HalfedgeId h = start;
    std::size_t n = 0, capacity = ring.capacity;
    double *x = ring.x, *y = ring.y, *z = ring.z;
    HalfedgeId* spoke = ring.spoke.data();
    do {
      if (n + 2 >= capacity) {
        ring.size = n;
        ring.reserve(n + 1);
        capacity = ring.capacity, x = ring.x, y = ring.y, z = ring.z, spoke = ring.spoke.data();
      }
      const Vec3 d = m.position(m.to(h)) - p;
      x[n] = d.x, y[n] = d.y, z[n] = d.z;
      spoke[n] = h;
      ++n;
      h = m.ccw_rotated(h);
    } while (h.valid() && h != start);
    ring.size = n;  // and ring.any_sharp stays false: ring.sharp is not read
    if (h.valid()) {
      on_sector(fit_sample(ring, true, 2.0 * std::numbers::pi), ring, std::size_t{0});
      return;
    }
    ring.clear();  // not expected: treat it like any other vertex
  }
  // Start a closed ring at a sharp spoke so every sector is a contiguous run.
  HalfedgeId first = start;
  if (!m.is_boundary(v) && kind >= VertexKind::Crease) {
    for_each_outgoing(m, v, [&](HalfedgeId h) {
      if (f.is_sharp(m.edge(h)) && !f.is_sharp(m.edge(first))) first = h;
    });
  }
  HalfedgeId h = first, last;
  do {
    ring.push(m.position(m.to(h)) - p, h, f.is_sharp(m.edge(h)));
    last = h;
    h = m.ccw_rotated(h);
  } while (h.valid() && h != first);
  const bool closed = h.valid();
  if (!closed) ring.push(m.position(m.from(Mesh::prev(last))) - p, HalfedgeId(), true);

  if (kind <= VertexKind::Dart) {
    // Smooth or dart: the whole ring, angles scaled to 2 pi (a dart's crease is ignored).
    on_sector(fit_sample(ring, true, 2.0 * std::numbers::pi), ring, std::size_t{0});
    return;
  }
  // Crease and corner: one fit per sector between consecutive sharp spokes, including the
  // two sharp neighbours that bound it.
  const double total = kind == VertexKind::Crease ? std::numbers::pi : 0.0;
  if (closed) {
    // The sector that wraps around ends at the first spoke.
    ring.push(Vec3(ring.x[0], ring.y[0], ring.z[0]), HalfedgeId(), true);
  }
  Sample& sector = sector_sample();
  std::size_t sector_begin = 0;
  for (std::size_t i = 1; i < ring.size; ++i) {
    if (!ring.sharp[i]) continue;
    sector.assign(ring, sector_begin, i - sector_begin + 1);
    on_sector(fit_sample(sector, false, total), ring, sector_begin);
    sector_begin = i;
  }
}

// The fitted surface of v at half of each smooth spoke's parameter, passed to
// sink(spoke, point); a degenerate sample gives the chord midpoint.
template <class Sink>
void vertex_estimates(const Mesh& m, const Features& f, VertexId v, Sink&& sink) {
  const Vec3 p = m.position(v);
  for_each_sector_fit(m, f, v, [&](const SampleFit& fit, const Sample& ring, std::size_t begin) {
    fit.half_points([&](std::size_t i, const Vec3& offset) {
      const std::size_t k = begin + i;
      if (ring.spoke[k].valid() && !(ring.any_sharp && ring.sharp[k]))
        sink(ring.spoke[k], p + offset);
    });
  });
}

}  // namespace

void LsfStencil::half_edge_estimates(const Mesh& m, const Features& f, VertexId v,
                                     std::span<Vec3> out) {
  vertex_estimates(m, f, v, [&](HalfedgeId s, const Vec3& point) { out[s.idx] = point; });
}

QuadricFit vertex_fit(const Mesh& m, const Features& f, VertexId v) {
  QuadricFit first;
  first.origin = m.position(v);
  bool have = false;
  if (f.kind(v) == VertexKind::Corner) return first;
  for_each_sector_fit(m, f, v, [&](const SampleFit& fit, const Sample&, std::size_t) {
    if (!have) first = fit.quadric(m.position(v)), have = true;
  });
  return first;
}

// The least ratio of the chord beyond an endpoint to the edge's own chord for which the
// 1-D rule fits its quadratic (spec 5 gap 3); below it the endpoint's estimate is linear.
constexpr double kCurveSpacingRatio = 0.2;

Vec3 lsf_curve_point(const Mesh& m, const Features& f, HalfedgeId h) {
  const VertexId a = m.from(h), b = m.to(h);
  // Quadratic through (prev, x, next) at chord parameters (-d0, 0, d1), evaluated at d1/2.
  auto endpoint_estimate = [&](VertexId x, VertexId next) {
    const Vec3& px = m.position(x);
    const Vec3& pn = m.position(next);
    const VertexId before = f.curve_beyond(x, next);
    if (!before.valid()) return 0.5 * (px + pn);  // polyline end: linear
    const Vec3& pb = m.position(before);
    const double d0 = distance(pb, px), d1 = distance(px, pn);
    // A neighbour beyond much nearer than the edge is long (an arc's last short chord before
    // a long straight one, issue 17's plate outline): its bend, extrapolated over the long
    // edge, would bow a straight edge by a large fraction of its length. Linear, as at an end.
    if (d0 <= 0 || d1 <= 0 || d0 < kCurveSpacingRatio * d1) return 0.5 * (px + pn);
    const double w_before = -d1 * d1 / (4.0 * d0 * (d0 + d1));
    const double w_x = (d0 + 0.5 * d1) / (2.0 * d0);
    const double w_next = (d0 + 0.5 * d1) / (2.0 * (d0 + d1));
    return w_before * pb + w_x * px + w_next * pn;
  };
  return 0.5 * (endpoint_estimate(a, b) + endpoint_estimate(b, a));
}

namespace {

// The guard's sector normal (issue 17, see sector_normal below), summed face by face: on even
// rings weighted by the sine of each face's angle at the vertex, on fans and zippers by the
// faces' areas, blended by the ratio of the longest to the shortest spoke (kEvenSpokes to
// kUnevenSpokes). e1, e2: the face's two spokes, counter-clockwise.
constexpr double kEvenSpokes = 3.0, kUnevenSpokes = 12.0;
// `flat`: every face so far within kFlatSine of the first one (see flat_ring below).
constexpr double kFlatSine = 0.5e-3;
struct NormalSum {
  Vec3 angle_sum, area_sum, first;
  double shortest = std::numeric_limits<double>::infinity(), longest = 0;
  bool flat = true;

  void add(const Vec3& e1, const Vec3& e2) {
    const Vec3 n = cross(e1, e2);
    const double l1 = dot(e1, e1), l2 = dot(e2, e2);
    if (dot(first, first) == 0) {
      first = n;
    } else if (flat) {
      const Vec3 c = cross(first, n);
      flat = dot(c, c) <= (kFlatSine * kFlatSine) * (dot(first, first) * dot(n, n)) &&
             dot(first, n) > 0;
    }
    area_sum += n;
    if (l1 * l2 > 0) angle_sum += (1.0 / std::sqrt(l1 * l2)) * n;
    shortest = std::min(shortest, std::min(l1, l2));
    longest = std::max(longest, std::max(l1, l2));
  }
  Vec3 normal() const {
    const double ratio = longest > 0 && shortest > 0 ? std::sqrt(longest / shortest) : 1.0;
    const double w = std::clamp((ratio - kEvenSpokes) / (kUnevenSpokes - kEvenSpokes), 0.0, 1.0);
    return normalized((1.0 - w) * normalized(angle_sum) + w * normalized(area_sum));
  }
};

// Smooth and dart vertices whose closed ring has kMinBatchValence..kMaxBatchValence points
// are fitted four at a time, one vertex per lane of lsf_math::V4d. Every lane runs the
// operations of fit_sample and half_points in the same order (the even- and odd-indexed
// points summed apart and then added, as the pair kernels do), so the results are
// bit-identical to the one-vertex path; what changes is that the angle bookkeeping, the
// reductions and the certified 5x5 solve of four vertices share their instructions, and
// nothing is summed across lanes. Lanes the fast solve cannot certify take solve_fit.
using lsf_math::V4d;
using lsf_math::V4i;
constexpr int kLanes = 4;
constexpr std::size_t kMinBatchValence = 5;  // below five points the general solve decides
constexpr std::size_t kMaxBatchValence = 12;

struct FitBatch {
  int lanes = 0;
  alignas(32) double ox[kLanes], oy[kLanes], oz[kLanes];  // the vertices V
  alignas(32) double x[kMaxBatchValence][kLanes];         // ring offsets P_i - V
  alignas(32) double y[kMaxBatchValence][kLanes];
  alignas(32) double z[kMaxBatchValence][kLanes];
  Vec3* dest[kMaxBatchValence][kLanes];  // where P_i's estimate goes (EstimateSlots)
  // Closed rings of smooth vertices: where the guard's normal (NormalSum::normal) and flat
  // flag of the lane's vertex go; null for a dart (its normal is its sector's).
  Vec3* normal[kLanes];
  std::uint8_t* flat[kLanes];
};

// Where the estimates go (see LsfStencil::edge_points): the edge's slot of one array for the
// estimate along its lower-numbered half-edge, of the other for the other one. Chosen by
// index, not by a branch: which half-edge is lower is a coin toss the predictor loses.
struct EstimateSlots {
  Vec3* lower;
  Vec3* upper;
  Vec3* at(EdgeId e, bool along_lower) const {
    return (along_lower ? lower : upper) + std::size_t{e.idx};
  }
};

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
    const V4d l12 = l1 * l2;
    const V4i positive = l12 > 0;
    const V4d w = 1.0 / lsf_math::sqrt(l12);
    ax = select(positive, ax + nx * w, ax), ay = select(positive, ay + ny * w, ay);
    az = select(positive, az + nz * w, az);
    shortest = min4(shortest, min4(l1, l2)), longest = max4(longest, max4(l1, l2));
  }
  for (int l = 0; l < b.lanes; ++l) {
    if (b.normal[l] == nullptr) continue;
    NormalSum sum;
    sum.angle_sum = Vec3(ax[l], ay[l], az[l]), sum.area_sum = Vec3(rx[l], ry[l], rz[l]);
    sum.first = Vec3(fx[l], fy[l], fz[l]);
    sum.shortest = shortest[l], sum.longest = longest[l], sum.flat = flat[l] != 0;
    *b.normal[l] = sum.normal();
    *b.flat[l] = sum.flat && dot(sum.first, sum.first) > 0;
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

using FitBatchFn = void (*)(const FitBatch&, std::size_t, bool);

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

std::atomic<bool> g_baseline_only{false};

FitBatchFn fit_batch_kernel() {
  static const bool avx2 = cpu_has_avx2();
  return avx2 && !g_baseline_only.load(std::memory_order_relaxed) ? fit_batch_avx2
                                                                  : fit_batch_baseline;
}

// The batches of one task: whole rings of smooth and dart vertices by valence, one-sided
// sectors of crease vertices by size. fit() runs a full batch through the kernel, which
// writes each estimate to its slot.
struct Batches {
  std::array<FitBatch, kMaxBatchValence + 1> ring, sector;
  FitBatchFn kernel = fit_batch_kernel();

  void fit(FitBatch& b, std::size_t n, bool closed) {
    kernel(b, n, closed);
    b.lanes = 0;
  }
  // Fits what is left: the unused lanes get copies of lane 0.
  void flush() {
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
};

// Walks v's ring into the batch of its valence when v is smooth or a dart (whose whole ring
// is fitted too) with a closed ring of kMinBatchValence..kMaxBatchValence points, and fits
// the batch when it is full; false, with nothing changed, for every other vertex. A dart's
// sharp spoke gets an estimate too: harmless, the sharp edge's point is the curve rule's.
bool batch_smooth_vertex(const Mesh& m, VertexId v, const EstimateSlots& slots, Batches& batches,
                         Vec3* normal, std::uint8_t* flat) {
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
  b.normal[l] = normal, b.flat[l] = flat;
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

// --- The edge-point guard (issue 17) --------------------------------------------------------
//
// The two endpoint fits are only as good as their samples: on CAD tessellations (fans,
// zipped strips, regions whose every vertex is a crease vertex, flat faces beside fillets) a
// one-sided or mixed sample extrapolates, by up to the edge's length. Each estimate is
// checked against what the surface's normals allow, and the edge point is built from the
// estimates that pass, in this order of preference:
//  1. the mean of the endpoint estimates that agree with the normals (both, or the better
//     conditioned one);
//  2. else the cubic Hermite midpoint of the edge from those normals (the chord midpoint when
//     the normals say the edge is straight: a planar region stays planar);
// and finally pulled back towards the chord while one of its child faces would turn more than
// 60 degrees from the normals.

// Faces whose normals are closer than this (sine of the angle) are coplanar: far below any
// dihedral of a curved surface's tessellation, above the rounding of float STL coordinates.
constexpr double kCoplanarSine = 1e-3;

// Planar patches are told by exact coplanarity, to the rounding of the coordinates: a corner
// within kPatchTol of the face's size plus kFloatRounding of its coordinates' magnitude (four
// float32 ulps: float STL coordinates of a CAD plane) from the plane. Not an angle: no two
// faces of a tessellated smooth surface are that flat, however fine.
constexpr double kPatchTol = 1e-6;
constexpr double kFloatRounding = 4.0 / (1 << 24);

[[gnu::always_inline]] inline bool coplanar(const Vec3& t0, const Vec3& t1,
                                            double sine = kCoplanarSine) {
  const Vec3 c = cross(t0, t1);
  return dot(c, c) <= (sine * sine) * (dot(t0, t0) * dot(t1, t1)) && dot(t0, t1) > 0;
}

// Whether face (p, q, r), of normal n = (q - p) x (r - p), lies, facing the same way, in the
// plane through p of normal t (unnormalised), to the rounding above (squared, without a root:
// the tolerance is taken as the root of the sum of its two terms' squares, times sqrt 2).
bool in_plane(const Vec3& t, const Vec3& p, const Vec3& q, const Vec3& r, const Vec3& n) {
  if (!(dot(n, t) > 0)) return false;
  const double magnitude = std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z)});
  const Vec3 pq = q - p, pr = r - p;
  const double size2 = std::max(dot(pq, pq), dot(pr, pr));
  const double tol2 = 2.0 * ((kPatchTol * kPatchTol) * size2 +
                             (kFloatRounding * magnitude) * (kFloatRounding * magnitude));
  const double dq = dot(pq, t), dr = dot(pr, t);
  return std::max(dq * dq, dr * dr) <= tol2 * dot(t, t);
}

bool in_plane(const Vec3& t, const Vec3& p, const Vec3& q, const Vec3& r) {
  return in_plane(t, p, q, r, cross(q - p, r - p));
}

// Whether the face of h (normal t, unnormalised) is coplanar with the face across one of its
// two other edges.
bool in_planar_patch(const Mesh& m, HalfedgeId h, const Vec3& t) {
  for (const HalfedgeId side : {Mesh::next(h), Mesh::prev(h)}) {
    const HalfedgeId across = m.twin(side);
    if (!across.valid()) continue;
    const Vec3 p = m.position(m.from(across)), q = m.position(m.to(across)),
               r = m.position(m.opposite(across));
    if (coplanar(t, triangle_normal(p, q, r)) && in_plane(t, p, q, r)) return true;
  }
  return false;
}

// How much of an edge end's face area (a fraction) must lie in the plane of the edge's faces
// for that plane to rule the edge (at a smooth vertex, of its ring; at a crease or corner
// vertex, of the sector: a crease-bounded plane fills it), and how much smaller than the
// plane's largest face there its other faces must be (a fraction): a flat face beside a fillet
// is several times wider than the fillet's strips, while the exactly planar split quads of a coarse
// torus or cylinder are as wide as their neighbours (on a coarse torus the angle creases,
// issue 17 item 5, cut bands whose sectors are two faces of a quad and one of the next).
constexpr double kPlaneAreaShare = 0.5;
constexpr double kPlaneDominance = 0.75;

// Whether the faces of from(h)'s crease-bounded sector that holds h (its whole ring when it
// is smooth) which lie in the plane of normal t (unnormalised), to the rounding of the
// coordinates, hold at least kPlaneAreaShare of the sector's face area and its largest face
// dominates the others (kPlaneDominance); `bends` is set when one
// of from(h)'s faces, in any sector, turns from t by more than kCoplanarSine (only asked while
// the answer can matter: when this returns true and `bends` was false).
bool planar_end(const Mesh& m, const Features& f, HalfedgeId h, const Vec3& t, bool& bends) {
  const VertexId v = m.from(h);
  const Vec3 p = m.position(v);
  double planar = 0, total = 0, largest_planar = 0, largest_other = 0;
  // Every face: whether it bends (and, for a smooth vertex, its share); then, at a crease or
  // corner vertex, the sector's shares.
  const bool whole_ring = f.kind(v) == VertexKind::Smooth;
  auto add = [&](HalfedgeId s, bool bend_only) {
    const Vec3 q = m.position(m.to(s)), r = m.position(m.opposite(s));
    const Vec3 n = cross(q - p, r - p);
    const bool near = coplanar(t, n);
    bends = bends || !near;
    if (bend_only) return;
    const double area = norm(n);
    total += area;
    if (near && in_plane(t, p, q, r, n)) {
      planar += area;
      largest_planar = std::max(largest_planar, area);
    } else {
      largest_other = std::max(largest_other, area);
    }
  };
  if (whole_ring) for_each_outgoing(m, v, [&](HalfedgeId s) { add(s, false); });
  if (!whole_ring) {  // the sector, as sector_normal walks it
    constexpr int kMaxWalk = 4096;
    HalfedgeId s = h;
    int steps = 0;
    do {
      add(s, false);
      s = ccw_within_patch(m, f, s);
    } while (s.valid() && s != h && ++steps < kMaxWalk);
    if (!s.valid()) {
      s = cw_within_patch(m, f, h);
      steps = 0;
      while (s.valid() && s != h && ++steps < kMaxWalk) {
        add(s, false);
        s = cw_within_patch(m, f, s);
      }
    }
  }
  const bool rules = total > 0 && planar >= kPlaneAreaShare * total &&
                     largest_other <= kPlaneDominance * largest_planar;
  // The faces outside the sector only tell whether something bends, which matters only when
  // the plane rules here, and not once a face has bent (the sector's faces were asked first).
  if (!whole_ring && rules && !bends) for_each_outgoing(m, v, [&](HalfedgeId s) { add(s, true); });
  return rules;
}

// How much wider across an edge a planar patch's face must be than the face on the other side
// for the edge to count as the patch's straight border.
constexpr double kPatchWidthRatio = 2.0;

// How far an endpoint estimate may be from the Hermite midpoint of the normals, as a fraction
// of the Hermite midpoint's own offset from the chord (plus 1e-3 of the chord).
constexpr double kHermiteSlack = 1.0;

// The child-fold pass: how many halving rounds before the edges of a face still folding go to
// their chords, and the cosine of the screening angle (45 degrees) against the parent face.
constexpr int kFoldRounds = 6;
constexpr double kScreenCosine = 0.7071067811865476;

// The normal of from(h)'s faces within the crease-bounded sector that holds half-edge h: on
// even rings weighted by the faces' angles at the vertex, on fans and zippers by their areas.
// Unit, or zero when the sector has no direction.
Vec3 sector_normal(const Mesh& m, const Features& f, HalfedgeId h) {
  // A smooth or dart vertex has one sector, its whole ring: walked from its own half-edge, so
  // the sum is the same, bit for bit, whichever spoke asks (and equals the per-vertex cache).
  if (f.kind(m.from(h)) <= VertexKind::Dart) h = m.halfedge(m.from(h));
  const Vec3 p = m.position(m.from(h));
  NormalSum sum;
  auto add = [&](HalfedgeId s) {
    sum.add(m.position(m.to(s)) - p, m.position(m.to(Mesh::next(s))) - p);
  };
  constexpr int kMaxWalk = 4096;  // a valence no mesh has; only guards a broken one
  // A smooth vertex has no sharp spoke and no boundary: its ring is walked without looking
  // at the features.
  const bool smooth = f.kind(m.from(h)) == VertexKind::Smooth;
  HalfedgeId s = h;
  int steps = 0;
  do {  // counter-clockwise up to a sharp spoke (or all the way round)
    add(s);
    s = smooth ? m.ccw_rotated(s) : ccw_within_patch(m, f, s);
  } while (s.valid() && s != h && ++steps < kMaxWalk);
  if (!s.valid() && !smooth) {  // then clockwise from h, the faces on its other side
    s = cw_within_patch(m, f, h);
    steps = 0;
    while (s.valid() && s != h && ++steps < kMaxWalk) {
      add(s);
      s = cw_within_patch(m, f, s);
    }
  }
  // Angle weights suit even rings (a hull's); on a fan or zipper (spokes of very different
  // lengths) the few short spokes' faces may belong to another surface piece (a fillet's end
  // touching a rounded corner): there the area-weighted normal, dominated by the long faces,
  // is the better guess.
  return sum.normal();
}

// The midpoint of the cubic Hermite curve from a to b whose tangents are the chord projected
// onto the tangent planes of n_a and n_b, scaled to the chord's length, relative to the
// chord midpoint: (T_a - T_b) / 8. Zero when a normal has no direction or lies along the
// chord (nothing to say).
[[gnu::always_inline]] inline Vec3 hermite_offset(const Vec3& chord, double length, const Vec3& na,
                                                  const Vec3& nb) {
  if (!(length > 0)) return {};
  const Vec3 ta = chord - dot(chord, na) * na, tb = chord - dot(chord, nb) * nb;
  const double la2 = dot(ta, ta), lb2 = dot(tb, tb), min2 = 0.01 * (length * length);
  if (!(la2 > min2) || !(lb2 > min2)) return {};
  return (length / 8.0) * ((1.0 / std::sqrt(la2)) * ta - (1.0 / std::sqrt(lb2)) * tb);
}

// Whether triangle (p, q, r) turns more than 60 degrees from the unit normal n (a degenerate
// one does not count).
[[gnu::always_inline]] inline bool turns_over_60(const Vec3& p, const Vec3& q, const Vec3& r,
                                                 const Vec3& n) {
  const Vec3 t = triangle_normal(p, q, r);
  const double d = dot(t, n);
  return d < 0 ? dot(t, t) > 0 : d * d < 0.25 * dot(t, t);  // cos < 1/2, without a root
}

// Pulls the edge point of edge a -> b towards the chord midpoint while a 1-to-4 child of one
// of its faces would turn more than 60 degrees from that face's normal (the other edges' points
// taken at their midpoints); at the midpoint when halving eight times is not enough. Face k
// is (a, b, opposite[k]) when normals[k] is its outward normal and (b, a, opposite[k]) when
// -normals[k] is (the test below is the same with both signs flipped).
Vec3 pull_back_folds(const Vec3& a, const Vec3& b, const std::array<Vec3, 2>& opposite,
                     const std::array<Vec3, 2>& normals, int sides, const Vec3& point) {
  const Vec3 mid = 0.5 * (a + b);
  auto folds = [&](const Vec3& q) {
    for (int k = 0; k < sides; ++k) {
      const Vec3 c = opposite[k], n = normals[k];
      const Vec3 ac = 0.5 * (a + c), bc = 0.5 * (b + c);
      if (turns_over_60(a, q, ac, n) || turns_over_60(q, b, bc, n) || turns_over_60(q, bc, ac, n))
        return true;
    }
    return false;
  };
  Vec3 q = point;
  bool folded = folds(q);  // (each point tested once: most are not pulled at all)
  for (int i = 0; i < 8 && folded; ++i) {
    q = mid + 0.5 * (q - mid);
    folded = folds(q);
  }
  return folded ? mid : q;
}

}  // namespace

namespace {

// What the edge guard reads of a vertex, packed in one record (the edge pass reads two per
// edge, at random): its guard normal when it has one sector (smooth or dart), and for a batched
// smooth vertex whether all its faces are within kFlatSine of one another (then the plane rule
// cannot fire at an edge between two such vertices, see guarded_edge_point).
struct alignas(32) GuardVertex {
  Vec3 normal;
  std::uint8_t one_sector = 0;
  std::uint8_t flat = 0;
};

template <class NormalOf>
Vec3 guarded_edge_point(const Mesh& m, const Features& f, NormalOf&& normal_of,
                        const GuardVertex* guard, EdgeId e, const Vec3& lower_estimate,
                        const Vec3& upper_estimate) {
  const HalfedgeId h0 = m.halfedge(e), h1 = m.twin(h0);
  const Vec3 average = 0.5 * (lower_estimate + upper_estimate);
  if (!h1.valid()) return average;
  // ha runs a -> b; its estimate is a's fit.
  const HalfedgeId ha = h0.idx < h1.idx ? h0 : h1, hb = m.twin(ha);
  const Vec3 a = m.position(m.from(ha)), b = m.position(m.to(ha));
  const Vec3 mid = 0.5 * (a + b), chord = b - a;
  // Planar regions stay planar. Both faces in one plane, or a face of a planar patch
  // (coplanar with a neighbour across one of its other edges) at least twice as wide across
  // the edge as the face on the other side (a flat face ending at a fillet, tangent or at a
  // shallow crease: issue 17's rounded box and plate), "in one plane" meaning to the rounding
  // of the coordinates (in_plane), never by an angle: a smooth surface's tessellation, however
  // fine, has no two faces that flat. The plane then rules the edge when it is most of both
  // ends' neighbourhoods and the rest bends away for real (planar_end): the one-sided or mixed
  // fits there bow a straight edge. (A regular cylinder's split quads are exactly planar too,
  // but they are a small part of their corners' rings: they keep their fits. Near a flat net
  // nothing bends by more than kCoplanarSine, so the fits, linear there, decide: the spectral
  // analysis linearises the scheme about exactly such a net.)
  const Vec3 c0 = m.position(m.opposite(ha)), c1 = m.position(m.opposite(hb));
  const Vec3 t0 = triangle_normal(a, b, c0), t1 = triangle_normal(b, a, c1);
  // The squared widths across the edge, times its length. (Squares throughout: this runs for
  // every edge of every level, and the roots cost as much as the rest.)
  const double w0 = dot(t0, t0), w1 = dot(t1, t1);
  // When every face at a and at b is within kFlatSine of one face there (flat, known for
  // the batched smooth vertices), every face there is within kCoplanarSine of t0 and of t1:
  // nothing bends, so on_plane is false, and its walks are skipped (the flat regions of a
  // CAD part, most of its edges after a level).
  const bool no_bend = guard != nullptr && guard[m.from(ha).idx].flat && guard[m.from(hb).idx].flat;
  auto on_plane = [&](const Vec3& t) {  // (only asked for the few exactly planar candidates)
    if (no_bend) return false;
    bool bends = false;
    return planar_end(m, f, ha, t, bends) && planar_end(m, f, hb, t, bends) && bends;
  };
  constexpr double kRatio2 = kPatchWidthRatio * kPatchWidthRatio;
  // coplanar() first: no root, and false for almost every edge of a curved surface.
  if (((coplanar(t0, t1) && in_plane(t0, b, a, c1)) ||
       (w0 >= kRatio2 * w1 && in_planar_patch(m, ha, t0))) &&
      on_plane(t0))
    return mid;
  if (w1 >= kRatio2 * w0 && in_planar_patch(m, hb, t1) && on_plane(t1)) return mid;
  const Vec3 na = normal_of(ha), nb = normal_of(hb);
  const double length2 = dot(chord, chord);
  const double length = std::sqrt(length2);
  const Vec3 hermite = hermite_offset(chord, length, na, nb);
  const Vec3 da = lower_estimate - mid - hermite, db = upper_estimate - mid - hermite;
  const double tolerance = kHermiteSlack * norm(hermite) + 1e-3 * length;
  const double tolerance2 = tolerance * tolerance;
  const bool a_ok = dot(da, da) <= tolerance2, b_ok = dot(db, db) <= tolerance2;
  Vec3 point = a_ok && b_ok ? average
               : a_ok       ? lower_estimate
               : b_ok       ? upper_estimate
                            : mid + hermite;
  // The fold guard against the normals: the children of both faces at the edge. A point
  // within a tenth of the narrower face's height of the chord turns no child by more than
  // about 11 degrees from its parent: not checked (most points of a fine level).
  const Vec3 offset = point - mid;
  if (dot(offset, offset) * length2 < 0.01 * std::min(w0, w1)) return point;
  const Vec3 n = normalized(na + nb);
  if (norm(n) == 0) return point;
  const std::array<Vec3, 2> opposite = {c0, c1};
  const std::array<Vec3, 2> normals = {n, -n};  // hb's face seen from a -> b is reversed
  return pull_back_folds(a, b, opposite, normals, 2, point);
}

}  // namespace

Vec3 lsf_guarded_edge_point(const Mesh& m, const Features& f, EdgeId e, const Vec3& lower_estimate,
                            const Vec3& upper_estimate) {
  return guarded_edge_point(
      m, f, [&](HalfedgeId h) { return sector_normal(m, f, h); }, nullptr, e, lower_estimate,
      upper_estimate);
}

Vec3 lsf_guarded_curve_point(const Mesh& m, const Features& f, EdgeId e, const Vec3& point) {
  const HalfedgeId h = m.halfedge(e), t = m.twin(h);
  const Vec3 a = m.position(m.from(h)), b = m.position(m.to(h));
  // As for smooth edges (guarded_edge_point): a point within a tenth of the narrower face's
  // height of the chord turns no child by more than about 11 degrees from its parent, and is
  // not checked (the sector normals are four walks round the ends).
  {
    const Vec3 chord = b - a, offset = point - 0.5 * (a + b);
    double narrowest = std::numeric_limits<double>::infinity();
    for (const HalfedgeId s : {h, t}) {
      if (!s.valid()) continue;
      const Vec3 w = cross(chord, m.position(m.opposite(s)) - a);
      narrowest = std::min(narrowest, dot(w, w));
    }
    if (dot(offset, offset) * dot(chord, chord) < 0.01 * narrowest) return point;
  }
  // Each side's children against that side's normals (sectors end at the sharp edge).
  std::array<Vec3, 2> opposite, normals;
  int sides = 0;
  for (const HalfedgeId s : {h, t}) {
    if (!s.valid()) continue;
    const Vec3 n = normalized(sector_normal(m, f, s) + sector_normal(m, f, Mesh::next(s)));
    if (norm(n) == 0) continue;
    // Seen from a -> b: the face of t runs b -> a, so its corners are swapped back below.
    opposite[sides] = m.position(m.opposite(s));
    normals[sides] = s == h ? n : -n;
    ++sides;
  }
  return pull_back_folds(a, b, opposite, normals, sides, point);
}

namespace {

// Whether a 1-to-4 child of face `face`, with the edge points `points`, turns more than 60
// degrees from the face's sector normals (the sum over its three corners). Screened first
// against the face itself: a child within 45 degrees of its parent is not checked further.
template <class NormalOf>
bool child_folds(const Mesh& m, NormalOf&& normal_of, std::span<const Vec3> points, FaceId face) {
  const HalfedgeId h0 = Mesh::halfedge(face, 0), h1 = Mesh::halfedge(face, 1),
                   h2 = Mesh::halfedge(face, 2);
  const Vec3 a = m.position(m.from(h0)), b = m.position(m.from(h1)), c = m.position(m.from(h2));
  const Vec3 ab = points[m.edge(h0).idx], bc = points[m.edge(h1).idx], ca = points[m.edge(h2).idx];
  const std::array<std::array<Vec3, 3>, 4> children = {
      {{a, ab, ca}, {ab, b, bc}, {ca, bc, c}, {ab, bc, ca}}};
  const Vec3 parent = triangle_normal(a, b, c);
  const double parent2 = dot(parent, parent);
  bool suspect = false;
  for (const auto& t : children) {  // cos < kScreenCosine, without a root
    const Vec3 n = triangle_normal(t[0], t[1], t[2]);
    const double d = dot(n, parent);
    suspect = suspect || d < 0 || d * d < (kScreenCosine * kScreenCosine) * (dot(n, n) * parent2);
  }
  if (!suspect) return false;
  const Vec3 n = normalized(normal_of(h0) + normal_of(h1) + normal_of(h2));
  if (norm(n) == 0) return false;
  for (const auto& t : children)
    if (turns_over_60(t[0], t[1], t[2], n)) return true;
  return false;
}

template <class NormalOf>
void guard_child_folds(const Mesh& m, NormalOf&& normal_of, std::span<Vec3> points,
                       std::span<std::uint8_t> marks) {
  const std::size_t nf = m.num_faces();
  auto midpoint = [&](EdgeId e) {
    const HalfedgeId h = m.halfedge(e);
    return 0.5 * (m.position(m.from(h)) + m.position(m.to(h)));
  };
  // Every face once (in parallel), then only the folding faces and their neighbours: the
  // faces whose edge points the last round moved.
  std::atomic<bool> any{false};
  parallel_for_each_index(nf, [&](std::size_t i) {
    marks[i] = child_folds(m, normal_of, points, FaceId(static_cast<std::uint32_t>(i)));
    if (marks[i]) any.store(true, std::memory_order_relaxed);
  });
  if (!any.load()) return;
  std::vector<std::uint32_t> folding;
  for (std::size_t i = 0; i < nf; ++i)
    if (marks[i]) folding.push_back(static_cast<std::uint32_t>(i));
  std::vector<std::uint32_t> candidates;
  for (int round = 0; round <= kFoldRounds && !folding.empty(); ++round) {
    // Halfway back towards the chord (the last round: onto it), each edge of each folding
    // face; an edge of two folding faces moves twice.
    candidates.clear();
    for (const std::uint32_t i : folding) {
      for (int k = 0; k < 3; ++k) {
        const HalfedgeId h = Mesh::halfedge(FaceId(i), k);
        const EdgeId e = m.edge(h);
        const Vec3 mid = midpoint(e);
        points[e.idx] = round == kFoldRounds ? mid : mid + 0.5 * (points[e.idx] - mid);
        candidates.push_back(i);
        if (m.twin(h).valid()) candidates.push_back(Mesh::face(m.twin(h)).idx);
      }
    }
    std::sort(candidates.begin(), candidates.end());
    candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
    folding.clear();
    for (const std::uint32_t i : candidates)
      if (child_folds(m, normal_of, points, FaceId(i))) folding.push_back(i);
  }
}

}  // namespace

void lsf_guard_child_folds(const Mesh& m, const Features& f, std::span<Vec3> points,
                           std::span<std::uint8_t> marks) {
  guard_child_folds(
      m, [&](HalfedgeId h) { return sector_normal(m, f, h); }, points, marks);
}

void set_lsf_baseline_kernels(bool baseline_only) {
  g_baseline_only.store(baseline_only, std::memory_order_relaxed);
}

void LsfStencil::edge_points(const Level& coarse, std::span<Vec3> out) const {
  const Mesh& m = coarse.mesh;
  const Features& f = coarse.features;
  // Each smooth edge gets one estimate from each endpoint: the one along the edge's
  // lower-numbered half-edge goes straight into `out`, the other into `twin_estimate` (one
  // slot per edge, not per half-edge: half the memory, and the averaging pass below reads
  // both arrays in order; it adds the two in either order, which floating-point addition
  // allows). Every half-edge belongs to one vertex, so the writes never collide.
  // Raw storage, left uninitialised (every slot read is written first), from the plain heap,
  // not a BigVector: glibc hands the same pages back at the next level or refinement
  // instead of mapping (and the kernel zeroing) fresh ones each time, about 5% of an
  // armadillo refinement; huge pages are still asked for when it is large.
  struct RawVec3s {
    Vec3* data;
    std::size_t size;
    explicit RawVec3s(std::size_t n) : data(std::allocator<Vec3>().allocate(n)), size(n) {}
    ~RawVec3s() { std::allocator<Vec3>().deallocate(data, size); }
    RawVec3s(const RawVec3s&) = delete;
    RawVec3s& operator=(const RawVec3s&) = delete;
  } twin_estimate(m.num_edges());
  advise_huge_pages(twin_estimate.data, m.num_edges() * sizeof(Vec3));
  const EstimateSlots slots{out.data(), twin_estimate.data};
  auto sink = [&](HalfedgeId s, const Vec3& point) {
    *slots.at(m.edge(s), s.idx < m.twin(s).idx) = point;
  };
  std::vector<GuardVertex> guard(m.num_vertices());
  parallel_for_each_range(m.num_vertices(), [&](std::size_t begin, std::size_t end) {
    Batches batches;
    for (std::size_t i = begin; i < end; ++i) {
      const VertexId v(static_cast<std::uint32_t>(i));
      const VertexKind kind = f.kind(v);
      const bool batched =
          kind <= VertexKind::Dart
              ? batch_smooth_vertex(m, v, slots, batches,
                                    kind == VertexKind::Smooth ? &guard[i].normal : nullptr,
                                    &guard[i].flat)
          : kind == VertexKind::Crease ? batch_crease_vertex(m, f, v, slots, batches)
                                       : false;
      if (!batched) vertex_estimates(m, f, v, sink);
      // The guard's normal of a one-sector vertex, once (crease and corner vertices' sector
      // normals are found where they are needed).
      if (kind <= VertexKind::Dart && !(batched && kind == VertexKind::Smooth) &&
          m.halfedge(v).valid())
        guard[i].normal = sector_normal(m, f, m.halfedge(v));
      guard[i].one_sector = kind <= VertexKind::Dart;
    }
    batches.flush();
  });
  auto normal_of = [&](HalfedgeId h) {
    const VertexId v = m.from(h);
    const GuardVertex& g = guard[v.idx];
    return g.one_sector ? g.normal : sector_normal(m, f, h);
  };
  // The guard reads, per edge, the corners of its two faces, their four positions and its ends'
  // guard records: a chain of dependent loads at random places, which the edges before it
  // cannot hide. So they are prefetched, a stage of the chain at a time, kPrefetch edges apart
  // (no result depends on it).
  const std::span<const HalfedgeId> edge_halfedge = m.edge_halfedges(), twins = m.twins();
  const std::span<const VertexId> corners = m.corner_vertices();
  const std::span<const Vec3> positions = m.positions();
  constexpr std::size_t kPrefetch = 6;
  parallel_for_each_range(m.num_edges(), [&](std::size_t begin, std::size_t end) {
    for (std::size_t e = begin; e < end; ++e) {
      if (e + 3 * kPrefetch < end) {  // the edge's twin and its first face's corners
        const HalfedgeId h = edge_halfedge[e + 3 * kPrefetch];
        __builtin_prefetch(&twins[h.idx]);
        __builtin_prefetch(&corners[h.idx]);
      }
      if (e + 2 * kPrefetch < end) {  // the other face's corners, the first face's positions
        const HalfedgeId h = edge_halfedge[e + 2 * kPrefetch], t = twins[h.idx];
        if (t.valid()) __builtin_prefetch(&corners[t.idx]);
        const VertexId a = corners[h.idx], b = corners[Mesh::next(h).idx];
        __builtin_prefetch(&positions[a.idx]);
        __builtin_prefetch(&positions[b.idx]);
        __builtin_prefetch(&positions[corners[Mesh::prev(h).idx].idx]);
        __builtin_prefetch(&guard[a.idx]);
        __builtin_prefetch(&guard[b.idx]);
      }
      if (e + kPrefetch < end) {  // the other face's far corner
        const HalfedgeId t = twins[edge_halfedge[e + kPrefetch].idx];
        if (t.valid()) __builtin_prefetch(&positions[corners[Mesh::prev(t).idx].idx]);
      }
      const EdgeId edge(static_cast<std::uint32_t>(e));
      if (f.is_sharp(edge)) {
        out[e] = lsf_guarded_curve_point(m, f, edge, lsf_curve_point(m, f, m.halfedge(edge)));
        continue;
      }
      out[e] =
          guarded_edge_point(m, f, normal_of, guard.data(), edge, out[e], twin_estimate.data[e]);
    }
  });
  // The children with every edge point known: the estimates are no longer needed, so their
  // storage holds the per-face marks.
  guard_child_folds(
      m, normal_of, out,
      std::span<std::uint8_t>(reinterpret_cast<std::uint8_t*>(twin_estimate.data), m.num_faces()));
}

}  // namespace stlrefine
