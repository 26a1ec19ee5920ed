// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <array>
#include <cstdint>
#include <span>

#include "core/schemes/split4_host.h"

namespace stlrefine {

//! A quadric s(u,v) = V + c1 u + c2 v + c3 u^2/2 + c4 uv + c5 v^2/2 fitted to a vertex's
//! ring (or one sector of it) in Welch-Witkin polar parameters.
struct QuadricFit {
  Vec3 origin;              //!< c0 = V
  std::array<Vec3, 5> c{};  //!< c1..c5
  bool valid = false;       //!< false when the sample was too degenerate to fit

  Vec3 evaluate(double u, double v) const {
    return origin + u * c[0] + v * c[1] + (0.5 * u * u) * c[2] + (u * v) * c[3] +
           (0.5 * v * v) * c[4];
  }
};

//! Fits the quadric to ring points with parameters (u_i, v_i) by damped least squares:
//! (S^T S + mu h^4 diag(0,0,1,1,1)) c = S^T q, h the mean parameter radius (spec 5 gap 1).
QuadricFit fit_quadric(const Vec3& origin, std::span<const Vec3> points,
                       std::span<const std::array<double, 2>> params, double mu = 1e-9);

//! Polar parameters of ring points around `origin` (Welch-Witkin): angles between
//! consecutive points scaled so they sum to `total_angle` (2 pi for a closed ring, pi for
//! a crease sector, 0 = keep the natural angles), radius = distance. `closed` means the
//! last point is followed by the first.
void polar_parameters(const Vec3& origin, std::span<const Vec3> points, bool closed,
                      double total_angle, std::span<std::array<double, 2>> params);

//! Which kernel fits smooth and dart vertices (and crease sectors) four at a time: Auto, on
//! x86-64 CPUs with AVX2 the one built for it, else the baseline one; Baseline, always the
//! baseline one. Both give bit-identical results (the tests that compare them choose).
enum class LsfKernel { Auto, Baseline };

//! Local Surface Fitting (Suzuki, Yamamoto, Kanai, Kimura et al.; spec section 5), on the
//! 1-to-4 host. Each edge point is the average of the two endpoint fits evaluated at half
//! the edge's parameter, guarded for CAD tessellations (lsf_guarded_edge_point). Creases and
//! boundaries: one-sided sector fits (angles scaled to pi at crease vertices, natural at corners),
//! and the 1-D chord-length quadratic along sharp edges, so the angle across a crease is kept.
//! Interpolating.
class LsfStencil final : public Split4Stencil {
 public:
  explicit LsfStencil(LsfKernel kernel = LsfKernel::Auto) : kernel_(kernel) {}
  void edge_points(const Level& coarse, std::span<Vec3> out) const override;
  bool interpolating() const override { return true; }

  //! The fitted surface of v evaluated at half of each outgoing half-edge's parameter,
  //! indexed by half-edge (sharp half-edges are left untouched). One fit per vertex and
  //! sector, so each vertex is fitted once per level, not once per edge.
  static void half_edge_estimates(const Mesh& mesh, const Features& features, VertexId v,
                                  std::span<Vec3> per_halfedge);

 private:
  LsfKernel kernel_;
};

//! The fit at v used for curvature: the whole ring (smooth, dart) or the first sector
//! (crease, boundary); invalid at corners and for degenerate samples.
QuadricFit vertex_fit(const Mesh& mesh, const Features& features, VertexId v);

//! 1-D analogue on a sharp edge a-b (spec 5 gap 3): for each endpoint, the quadratic
//! through its curve neighbours in chord-length parameters evaluated at the edge's
//! half-parameter, averaged over both endpoints. Where the curve ends at one endpoint (a
//! polyline end, or a corner it does not continue through on one circle), the other
//! endpoint's quadratic alone (issue 17: the spec's linear end estimate kept half the arc's
//! sagitta next to the plate outline's corners); the chord midpoint when both end there.
Vec3 lsf_curve_point(const Mesh& mesh, const Features& features, HalfedgeId h);

//! The edge point of smooth edge e from its two endpoint estimates (`lower_estimate` by the
//! fit at the start of e's lower-numbered half-edge, `upper_estimate` by the other end's),
//! guarded for CAD tessellations (issue 17): the chord midpoint when the edge lies in a plane
//! (its faces coplanar to the rounding of their coordinates, the plane most of both ends'
//! sectors and something there bending away from it); else estimates that disagree with the
//! Hermite midpoint of the sector normals are dropped (both dropped: the Hermite midpoint),
//! and the point is pulled towards the chord while a child face would turn more than 60
//! degrees from them.
Vec3 lsf_guarded_edge_point(const Mesh& mesh, const Features& features, EdgeId e,
                            const Vec3& lower_estimate, const Vec3& upper_estimate);

//! The point of sharp edge e from the 1-D rule (lsf_curve_point), pulled towards the chord
//! while a child of a face on either side would turn more than 60 degrees from that side's
//! normals (issue 17: creases the angle found on a coarse smooth surface); not checked when
//! the point is within a tenth of the narrower face's height of the chord.
Vec3 lsf_guarded_curve_point(const Mesh& mesh, const Features& features, EdgeId e,
                             const Vec3& point);

//! The last pass of LsfStencil::edge_points: `points` holds one point per edge; while a
//! 1-to-4 child of a face turns more than 60 degrees from the face's sector normals, its three
//! edge points are moved halfway to their chord midpoints (after six rounds onto them).
//! `marks` has room for a byte per face (scratch).
void lsf_guard_child_folds(const Mesh& mesh, const Features& features, std::span<Vec3> points,
                           std::span<std::uint8_t> marks);

}  // namespace stlrefine
