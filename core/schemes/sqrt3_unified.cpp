// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/sqrt3_unified.h"

#include "core/parallel.h"
#include "core/schemes/crease_rules.h"

namespace stlrefine {

BigVector<double> LinLuoStencil::initial_alpha(const Level& input) const {
  BigVector<double> alpha(input.mesh.num_vertices());
  parallel_for_each_index(alpha.size(), [&](std::size_t i) {
    // Crease and corner vertices lie on feature lines: a part may keep those exact.
    alpha[i] = input.features.cuts_ring(VertexId(static_cast<std::uint32_t>(i))) ? alpha_features_
                                                                                 : alpha_;
  });
  return alpha;
}

namespace {

// Old vertex: P + (1 - alpha) Delta. Alpha 1 copies the position, so interpolation is
// bit-exact even for -0.0.
Vec3 relaxed(const Vec3& p, double alpha, const Vec3& delta) {
  const double keep = 1.0 - alpha;
  return keep == 0.0 ? p : p + keep * delta;
}

// Face point: the sum of (P - alpha_P Delta(P)) / 3 over the corners.
template <class DeltaOf>
Vec3 unified_face_point(const Sqrt3Step& step, FaceId f, DeltaOf&& delta_of) {
  Vec3 sum;
  for (const VertexId v : step.mesh.face_vertices(f))
    sum += step.mesh.position(v) - step.alpha[v.idx] * delta_of(v);
  return sum * (1.0 / 3.0);
}

}  // namespace

Vec3 LinLuoStencil::face_point(const Sqrt3Step& step, FaceId f) const {
  return unified_face_point(step, f, [&](VertexId v) { return relaxation_.displacement(step, v); });
}

Vec3 LinLuoStencil::vertex_point(const Sqrt3Step& step, VertexId v) const {
  return relaxed(step.mesh.position(v), step.alpha[v.idx], relaxation_.displacement(step, v));
}

void LinLuoStencil::points(const Sqrt3Step& step, Sqrt3Points out) const {
  const Mesh& m = step.mesh;
  // Each Delta is used by the vertex itself and by every face around it: compute it once.
  BigVector<Vec3> delta(m.num_vertices());
  parallel_for_each_index(m.num_vertices(), [&](std::size_t i) {
    const VertexId v(static_cast<std::uint32_t>(i));
    delta[i] = relaxation_.displacement(step, v);
    out.vertices[i] = relaxed(m.position(v), step.alpha[i], delta[i]);
  });
  parallel_for_each_index(m.num_faces(), [&](std::size_t fi) {
    const FaceId f(static_cast<std::uint32_t>(fi));
    if (!step.has_face_point(f)) return;
    out.faces[fi] = unified_face_point(step, f, [&](VertexId v) { return delta[v.idx]; });
  });
}

std::array<Vec3, 2> LinLuoStencil::curve_points(const Sqrt3Step& step, HalfedgeId h) const {
  //   P_i-1 ------ P_i --x----x-- P_i+1 ------ P_i+2
  //                     1/3  2/3      each: B-spline point - displacement interpolated
  //                                   from Delta_i, Delta_i+1 at the point's parameter
  const std::array<Vec3, 4> w = curve_window(step.mesh, step.features, h);
  const Vec3 d_from = step.alpha[step.mesh.from(h).idx] * curve_displacement(w[0], w[1], w[2]);
  const Vec3 d_to = step.alpha[step.mesh.to(h).idx] * curve_displacement(w[1], w[2], w[3]);
  const std::array<Vec3, 2> b = bspline_trisection(w);
  return {b[0] - (2.0 / 3.0) * d_from - (1.0 / 3.0) * d_to,
          b[1] - (1.0 / 3.0) * d_from - (2.0 / 3.0) * d_to};
}

}  // namespace stlrefine
