// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/lsf.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>
#include <vector>

#include "core/parallel.h"
#include "core/schemes/crease_rules.h"

namespace stlrefine {

namespace {

double angle_between(const Vec3& a, const Vec3& b) {
  return std::atan2(norm(cross(a, b)), dot(a, b));
}

// Relative singular value of the scaled design matrix below which a direction counts as
// undetermined. Well-spread rings sit above 1e-1; a perturbed crease strip near 1e-5.
constexpr double kSingularCutoff = 1e-3;
// The damping used for such samples: far above their tiny singular values squared, so the
// undetermined second-order combination is set to its minimum norm, as spec 5 gap 1 does
// for valence < 5, and small enough that the determined terms are not biased (~1e-6).
constexpr double kIllConditionedMu = 1e-6;

// The 5x5 symmetric systems of the fit are small enough that Eigen's general-size LDLT
// machinery (dynamic blocks, blocked triangular solves) costs more than the arithmetic;
// it was the largest share of LSF's time. Ldlt5 is the same algorithm written for 5x5:
// Eigen 3.4's LDLT (lower storage, diagonal pivoting on the largest remaining |d|, the
// same order of every sum and update), so the results are bit for bit those of
// Eigen::LDLT. They must be: the damping of spec 5 gap 1 (mu = 1e-9) leaves the fits of
// low-valence vertices so ill-conditioned that a last-bit change grows to ~1e-8 of the
// model size one level later.
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

// True when the unit-diagonal (Jacobi-scaled) normal matrix has a pivot below the squared
// cut-off: a test independent of units and parameter scale, cheap enough for every vertex.
bool poorly_conditioned(const Mat5& normal) {
  std::array<double, 5> inv_sqrt;
  for (int i = 0; i < 5; ++i) {
    if (normal[i][i] <= 0) return true;
    inv_sqrt[i] = 1.0 / std::sqrt(normal[i][i]);
  }
  Mat5 unit;
  for (int i = 0; i < 5; ++i)
    for (int j = 0; j <= i; ++j) unit[j][i] = (inv_sqrt[i] * normal[j][i]) * inv_sqrt[j];
  const Ldlt5 ldlt(unit);
  return !ldlt.success || ldlt.min_pivot() < kSingularCutoff * kSingularCutoff;
}

}  // namespace

void polar_parameters(const Vec3& origin, std::span<const Vec3> points, bool closed,
                      double total_angle, std::span<std::array<double, 2>> params) {
  const std::size_t n = points.size();
  if (n == 0) return;
  const std::size_t gaps = closed ? n : n - 1;
  // One atan2 per gap: params[i][0] holds the angle of gap i until the walk below
  // overwrites it with point i's own parameters.
  double sum = 0;
  const Vec3 first = points[0] - origin;
  Vec3 here = first;
  for (std::size_t i = 0; i < gaps; ++i) {
    const Vec3 next = i + 1 < n ? points[i + 1] - origin : first;
    const double angle = angle_between(here, next);
    params[i][0] = angle;
    sum += angle;
    here = next;
  }
  const double scale = (total_angle > 0 && sum > 0) ? total_angle / sum : 1.0;
  double phi = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double angle = params[i][0];  // unset for the last point of an open fan: unused
    const double r = distance(points[i], origin);
    if (i == 0) {
      params[i] = {r, 0.0};  // r cos 0, r sin 0
    } else {
      params[i] = {r * std::cos(phi), r * std::sin(phi)};
    }
    if (i + 1 < n) phi += scale * angle;
  }
}

QuadricFit fit_quadric(const Vec3& origin, std::span<const Vec3> points,
                       std::span<const std::array<double, 2>> params, double mu) {
  // Normal equations (S^T S) c = S^T q, accumulated point by point (lower part only).
  Mat5 normal{};
  std::array<std::array<double, 3>, 5> rhs{};
  double mean_radius = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto [u, v] = params[i];
    const std::array<double, 5> row = {u, v, 0.5 * u * u, u * v, 0.5 * v * v};
    const Vec3 q = points[i] - origin;
    for (int c = 0; c < 5; ++c) {
      for (int r = c; r < 5; ++r) normal[c][r] += row[c] * row[r];
      rhs[c][0] += q.x * row[c];
      rhs[c][1] += q.y * row[c];
      rhs[c][2] += q.z * row[c];
    }
    mean_radius += std::hypot(u, v);
  }
  QuadricFit fit;
  fit.origin = origin;
  if (points.empty()) return fit;
  mean_radius /= static_cast<double>(points.size());
  // Five or more points can still be nearly degenerate: the side points of a crease vertex
  // on a developable strip lie close to two lines parallel to the crease (a degenerate
  // conic), and the exact least-squares quadric then swings far off the surface (50 mm on
  // a 10 mm cylinder in the fidelity bench). Such samples are damped firmly.
  if (points.size() >= 5 && poorly_conditioned(normal)) mu = std::max(mu, kIllConditionedMu);
  // Damp only the second-order terms: below valence 5 S^T S is singular, and the damped
  // solution tends to the interpolating quadric with the smallest curvature terms.
  const double damping = mu * std::pow(mean_radius, 4);
  for (int k = 2; k < 5; ++k) normal[k][k] += damping;
  const Ldlt5 ldlt(normal);
  if (!ldlt.success || !ldlt.positive) return fit;
  std::array<std::array<double, 3>, 5> c = rhs;
  ldlt.solve(c);
  for (const auto& row : c)
    for (double x : row)
      if (!std::isfinite(x)) return fit;
  // A rank-deficient linear part (collinear sample) shows as a tiny pivot: refuse it.
  if (ldlt.min_pivot() <= 1e-14 * ldlt.max_pivot()) return fit;
  for (int k = 0; k < 5; ++k) fit.c[k] = {c[k][0], c[k][1], c[k][2]};
  fit.valid = true;
  return fit;
}

namespace {

//! Walks v's ring once and fits one quadric per sector (the whole ring for smooth and dart
//! vertices), calling on_sector(fit, spokes, sharp, params) for each: spokes[i] is the
//! outgoing half-edge to ring point i (invalid for the point that closes an open fan),
//! params[i] its (u, v). Crease sectors are scaled to pi, corners keep natural angles.
template <class OnSector>
void for_each_sector_fit(const Mesh& m, const Features& f, VertexId v, OnSector&& on_sector) {
  thread_local std::vector<Vec3> ring;
  thread_local std::vector<HalfedgeId> spoke;
  thread_local std::vector<std::uint8_t> sharp;
  thread_local std::vector<std::array<double, 2>> params;
  ring.clear(), spoke.clear(), sharp.clear();
  const HalfedgeId start = m.halfedge(v);
  if (!start.valid()) return;
  const VertexKind kind = f.kind(v);
  // Start a closed ring at a sharp spoke so every sector is a contiguous run.
  HalfedgeId first = start;
  if (!m.is_boundary(v) && kind >= VertexKind::Crease) {
    for_each_outgoing(m, v, [&](HalfedgeId h) {
      if (f.is_sharp(m.edge(h)) && !f.is_sharp(m.edge(first))) first = h;
    });
  }
  HalfedgeId h = first, last;
  do {
    ring.push_back(m.position(m.to(h)));
    spoke.push_back(h);
    sharp.push_back(f.is_sharp(m.edge(h)));
    last = h;
    h = m.ccw_rotated(h);
  } while (h.valid() && h != first);
  const bool closed = h.valid();
  if (!closed) {
    ring.push_back(m.position(m.from(Mesh::prev(last))));
    spoke.push_back(HalfedgeId());
    sharp.push_back(1);
  }
  params.resize(ring.size());
  const Vec3& p = m.position(v);

  auto fit_sector = [&](std::size_t begin, std::size_t count, bool sector_closed,
                        double total_angle) {
    const std::span<const Vec3> pts(ring.data() + begin, count);
    const std::span<std::array<double, 2>> prm(params.data() + begin, count);
    polar_parameters(p, pts, sector_closed, total_angle, prm);
    on_sector(fit_quadric(p, pts, prm), std::span<const HalfedgeId>(spoke.data() + begin, count),
              std::span<const std::uint8_t>(sharp.data() + begin, count),
              std::span<const std::array<double, 2>>(prm));
  };

  if (kind <= VertexKind::Dart) {
    // Smooth or dart: the whole ring, angles scaled to 2 pi (a dart's crease is ignored).
    fit_sector(0, ring.size(), true, 2.0 * std::numbers::pi);
    return;
  }
  // Crease and corner: one fit per sector between consecutive sharp spokes, including the
  // two sharp neighbours that bound it.
  const double total = kind == VertexKind::Crease ? std::numbers::pi : 0.0;
  if (closed) {
    ring.push_back(ring.front());  // the sector that wraps around ends at the first spoke
    spoke.push_back(HalfedgeId());
    sharp.push_back(1);
    params.resize(ring.size());
  }
  std::size_t sector_begin = 0;
  for (std::size_t i = 1; i < ring.size(); ++i) {
    if (!sharp[i]) continue;
    fit_sector(sector_begin, i - sector_begin + 1, false, total);
    sector_begin = i;
  }
}

}  // namespace

namespace {

// The fitted surface of v at half of each smooth spoke's parameter, passed to
// sink(spoke, point); a degenerate sample gives the chord midpoint.
template <class Sink>
void vertex_estimates(const Mesh& m, const Features& f, VertexId v, Sink&& sink) {
  const Vec3& p = m.position(v);
  for_each_sector_fit(
      m, f, v,
      [&](const QuadricFit& fit, std::span<const HalfedgeId> spokes,
          std::span<const std::uint8_t> sharp, std::span<const std::array<double, 2>> prm) {
        for (std::size_t i = 0; i < spokes.size(); ++i) {
          const HalfedgeId s = spokes[i];
          if (!s.valid() || sharp[i]) continue;
          sink(s, fit.valid ? fit.evaluate(0.5 * prm[i][0], 0.5 * prm[i][1])
                            : 0.5 * (p + m.position(m.to(s))));
        }
      });
}

}  // namespace

void LsfStencil::half_edge_estimates(const Mesh& m, const Features& f, VertexId v,
                                     std::span<Vec3> out) {
  vertex_estimates(m, f, v, [&](HalfedgeId s, const Vec3& point) { out[s.idx] = point; });
}

QuadricFit vertex_fit(const Mesh& m, const Features& f, VertexId v) {
  QuadricFit first;
  bool have = false;
  if (f.kind(v) == VertexKind::Corner) return first;
  for_each_sector_fit(m, f, v,
                      [&](const QuadricFit& fit, std::span<const HalfedgeId>,
                          std::span<const std::uint8_t>, std::span<const std::array<double, 2>>) {
                        if (!have) first = fit, have = true;
                      });
  return first;
}

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
    if (d0 <= 0 || d1 <= 0) return 0.5 * (px + pn);
    const double w_before = -d1 * d1 / (4.0 * d0 * (d0 + d1));
    const double w_x = (d0 + 0.5 * d1) / (2.0 * d0);
    const double w_next = (d0 + 0.5 * d1) / (2.0 * (d0 + d1));
    return w_before * pb + w_x * px + w_next * pn;
  };
  return 0.5 * (endpoint_estimate(a, b) + endpoint_estimate(b, a));
}

void LsfStencil::edge_points(const Level& coarse, std::span<Vec3> out) const {
  const Mesh& m = coarse.mesh;
  const Features& f = coarse.features;
  // Each smooth edge gets one estimate from each endpoint: the one along the edge's own
  // half-edge goes straight into `out`, the other into `twin_estimate` (one slot per edge,
  // not per half-edge: half the memory, and the averaging pass below reads both arrays in
  // order). Every half-edge belongs to one vertex, so the writes never collide.
  // std::array, unlike Vec3, is left uninitialised: every slot read is written first.
  BigVector<std::array<double, 3>> twin_estimate(m.num_edges());
  parallel_for_each_index(m.num_vertices(), [&](std::size_t v) {
    vertex_estimates(m, f, VertexId(static_cast<std::uint32_t>(v)),
                     [&](HalfedgeId s, const Vec3& point) {
                       const EdgeId e = m.edge(s);
                       if (m.halfedge(e) == s)
                         out[e.idx] = point;
                       else
                         twin_estimate[e.idx] = {point.x, point.y, point.z};
                     });
  });
  parallel_for_each_index(m.num_edges(), [&](std::size_t e) {
    const EdgeId edge(static_cast<std::uint32_t>(e));
    if (f.is_sharp(edge)) {
      out[e] = lsf_curve_point(m, f, m.halfedge(edge));
      return;
    }
    const auto& [x, y, z] = twin_estimate[e];
    out[e] = 0.5 * (out[e] + Vec3(x, y, z));
  });
}

}  // namespace stlrefine
