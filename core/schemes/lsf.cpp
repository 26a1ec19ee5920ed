// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/lsf.h"

#include <Eigen/Dense>
#include <cmath>
#include <numbers>
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

// True when the unit-diagonal (Jacobi-scaled) normal matrix has a pivot below the squared
// cut-off: a test independent of units and parameter scale, cheap enough for every vertex.
bool poorly_conditioned(const Eigen::Matrix<double, 5, 5>& normal) {
  const Eigen::Matrix<double, 5, 1> diag = normal.diagonal();
  if ((diag.array() <= 0).any()) return true;
  const Eigen::Matrix<double, 5, 1> inv_sqrt = diag.cwiseSqrt().cwiseInverse();
  const Eigen::Matrix<double, 5, 5> unit = inv_sqrt.asDiagonal() * normal * inv_sqrt.asDiagonal();
  const Eigen::LDLT<Eigen::Matrix<double, 5, 5>> ldlt(unit);
  return ldlt.info() != Eigen::Success ||
         ldlt.vectorD().minCoeff() < kSingularCutoff * kSingularCutoff;
}

}  // namespace

void polar_parameters(const Vec3& origin, std::span<const Vec3> points, bool closed,
                      double total_angle, std::span<std::array<double, 2>> params) {
  const std::size_t n = points.size();
  const std::size_t gaps = closed ? n : n - 1;
  double sum = 0;
  for (std::size_t i = 0; i < gaps; ++i)
    sum += angle_between(points[i] - origin, points[(i + 1) % n] - origin);
  const double scale = (total_angle > 0 && sum > 0) ? total_angle / sum : 1.0;
  double phi = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double r = distance(points[i], origin);
    params[i] = {r * std::cos(phi), r * std::sin(phi)};
    if (i + 1 < n) phi += scale * angle_between(points[i] - origin, points[i + 1] - origin);
  }
}

QuadricFit fit_quadric(const Vec3& origin, std::span<const Vec3> points,
                       std::span<const std::array<double, 2>> params, double mu) {
  using Mat5 = Eigen::Matrix<double, 5, 5>;
  using Mat53 = Eigen::Matrix<double, 5, 3>;
  Mat5 normal = Mat5::Zero();
  Mat53 rhs = Mat53::Zero();
  double mean_radius = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto [u, v] = params[i];
    Eigen::Matrix<double, 5, 1> row;
    row << u, v, 0.5 * u * u, u * v, 0.5 * v * v;
    const Vec3 q = points[i] - origin;
    normal.selfadjointView<Eigen::Lower>().rankUpdate(row);
    rhs += row * Eigen::RowVector3d(q.x, q.y, q.z);
    mean_radius += std::hypot(u, v);
  }
  normal.triangularView<Eigen::StrictlyUpper>() = normal.transpose();
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
  for (int k = 2; k < 5; ++k) normal(k, k) += damping;
  const Eigen::LDLT<Mat5> ldlt(normal);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return fit;
  const Mat53 c = ldlt.solve(rhs);
  if (!c.allFinite()) return fit;
  // A rank-deficient linear part (collinear sample) shows as a tiny pivot: refuse it.
  const auto d = ldlt.vectorD();
  if (d.minCoeff() <= 1e-14 * d.maxCoeff()) return fit;
  for (int k = 0; k < 5; ++k) fit.c[k] = {c(k, 0), c(k, 1), c(k, 2)};
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

void LsfStencil::half_edge_estimates(const Mesh& m, const Features& f, VertexId v,
                                     std::span<Vec3> out) {
  const Vec3& p = m.position(v);
  for_each_sector_fit(
      m, f, v,
      [&](const QuadricFit& fit, std::span<const HalfedgeId> spokes,
          std::span<const std::uint8_t> sharp, std::span<const std::array<double, 2>> prm) {
        for (std::size_t i = 0; i < spokes.size(); ++i) {
          const HalfedgeId s = spokes[i];
          if (!s.valid() || sharp[i]) continue;
          // A degenerate sample falls back to the chord midpoint.
          out[s.idx] = fit.valid ? fit.evaluate(0.5 * prm[i][0], 0.5 * prm[i][1])
                                 : 0.5 * (p + m.position(m.to(s)));
        }
      });
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
  BigVector<Vec3> estimate(m.num_halfedges());
  parallel_for_each_index(m.num_vertices(), [&](std::size_t v) {
    half_edge_estimates(m, f, VertexId(static_cast<std::uint32_t>(v)), estimate);
  });
  parallel_for_each_index(m.num_edges(), [&](std::size_t e) {
    const EdgeId edge(static_cast<std::uint32_t>(e));
    const HalfedgeId h = m.halfedge(edge);
    out[e] = f.is_sharp(edge) ? lsf_curve_point(m, f, h)
                              : 0.5 * (estimate[h.idx] + estimate[m.twin(h).idx]);
  });
}

}  // namespace stlrefine
