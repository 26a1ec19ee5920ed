// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/sqrt3_interp.h"

#include <cmath>
#include <numbers>

#include "core/parallel.h"
#include "core/schemes/crease_rules.h"

namespace stlrefine {

double LabsikGreinerStencil::extraordinary_weight(int n, int i) {
  // The real square root of the paper's double-step rule (14)-(15) (spec 3.3): two steps
  // of it are eq. (14)-(15), with the n = 3, 4 special cases coming out of the same formula.
  const double t = 2.0 * std::numbers::pi * (i - 0.5) / n;
  const double second = n >= 5 ? (2.0 / 3.0) * std::cos(2.0 * t) : 0.0;
  return (1.0 / 3.0 + (2.0 / std::numbers::sqrt3) * std::cos(t) + second) / n;
}

LabsikGreinerStencil::LabsikGreinerStencil() : weights_(kCachedValences) {
  for (int n = 3; n < kCachedValences; ++n) {
    weights_[n].resize(n);
    for (int i = 0; i < n; ++i) weights_[n][i] = extraordinary_weight(n, i);
  }
}

namespace {

// A vertex's valence when it is an extraordinary centre (an interior vertex whose ring no
// sharp edge cuts, valence != 6), else 0. Sharp vertices are never centres, and neither are
// valence-2 ones (two faces folded onto each other): the rule's weights exist for n >= 3
// only, and reading them at n = 2 read an empty table (a crash, found by fuzzing).
int extraordinary_valence(const Mesh& m, const Features& f, VertexId v) {
  if (f.cuts_ring(v) || m.is_isolated(v) || m.is_boundary(v)) return 0;
  const int valence = m.valence(v);
  return valence == 6 || valence < 3 ? 0 : valence;
}

std::vector<int> extraordinary_valences(const Mesh& m, const Features& f) {
  std::vector<int> n(m.num_vertices(), 0);
  parallel_for_each_index(m.num_vertices(), [&](std::size_t i) {
    n[i] = extraordinary_valence(m, f, VertexId(static_cast<std::uint32_t>(i)));
  });
  return n;
}

// The two far neighbours of corner a = from(h) of triangle (a, b, c): its ring vertices
// opposite b and opposite c, reached by walking two triangles around a (counter-clockwise
// past c, clockwise past b). Where the walk would cross a sharp edge the lattice point
// 2a - b (resp. 2a - c) stands in.
//
//         c ---- tip
//        / \    /
//   far_b ---- a ---- b         far_b = opposite b (2a - b),  far_c = opposite c (2a - c)
//      /    \ /  \   /
//   ...    far_c -- tip
Vec3 far_neighbours(const Mesh& m, const Features& f, HalfedgeId h) {
  const Vec3& a = m.position(m.from(h));
  HalfedgeId ccw = ccw_within_patch(m, f, h);
  if (ccw.valid()) ccw = ccw_within_patch(m, f, ccw);
  HalfedgeId cw = cw_within_patch(m, f, h);
  if (cw.valid()) cw = cw_within_patch(m, f, cw);
  const Vec3 far_b =
      ccw.valid() ? m.position(m.opposite(ccw)) : reflected_through(a, m.position(m.to(h)));
  const Vec3 far_c =
      cw.valid() ? m.position(m.to(cw)) : reflected_through(a, m.position(m.opposite(h)));
  return far_b + far_c;
}

//  lattice coords, triangle p1=(0,0) p2=(1,0) p3=(0,1), q at its centroid:
//  j= 2:                 c(-1,2)      c(0,2)
//  j= 1:          b(-1,1)      a(0,1)       b(1,1)
//  j= 0:   c(-1,0)      a(0,0)   q   a(1,0)       c(2,0)
//  j=-1:          c(0,-1)      b(1,-1)      c(2,-1)
//  q = 32/81 sum a - 1/81 sum b - 2/81 sum c
Vec3 regular_point(const Mesh& m, const Features& f, FaceId face) {
  Vec3 a, b, c;
  for (int k = 0; k < 3; ++k) {
    const HalfedgeId h = Mesh::halfedge(face, k);
    a += m.position(m.from(h));
    b += tip_across(m, f, h);
    c += far_neighbours(m, f, h);
  }
  return LabsikGreinerStencil::kCorner * a + LabsikGreinerStencil::kTip * b +
         LabsikGreinerStencil::kFar * c;
}

}  // namespace

Vec3 LabsikGreinerStencil::extraordinary_point(const Mesh& m, HalfedgeId h, int n) const {
  //        p2 ---- p1
  //       /  \ q  /  \       q = 2/3 p + sum_i alpha_i p_i, ring counted from p0 = to(h)
  //    p3 ---- p ---- p0     towards p1 (the triangle's other corner)
  //       \  /    \  /
  //        .. ---- p_n-1
  Vec3 sum = kCentre * m.position(m.from(h));
  if (n < kCachedValences) {
    const std::vector<double>& w = weights_[n];
    for_each_ring_vertex_from(m, h, [&](int i, VertexId v) { sum += w[i] * m.position(v); });
  } else {
    for_each_ring_vertex_from(
        m, h, [&](int i, VertexId v) { sum += extraordinary_weight(n, i) * m.position(v); });
  }
  return sum;
}

Vec3 LabsikGreinerStencil::face_point_from(const Mesh& m, const Features& f, FaceId face,
                                           const std::array<int, 3>& extraordinary) const {
  // Several extraordinary corners (coarsest level only): the average of their rules.
  Vec3 sum;
  int centres = 0;
  for (int k = 0; k < 3; ++k) {
    if (extraordinary[k] == 0) continue;
    sum += extraordinary_point(m, Mesh::halfedge(face, k), extraordinary[k]);
    ++centres;
  }
  return centres == 0 ? regular_point(m, f, face) : centres == 1 ? sum : sum * (1.0 / centres);
}

Vec3 LabsikGreinerStencil::face_point(const Sqrt3Step& step, FaceId face) const {
  std::array<int, 3> n{};
  for (int k = 0; k < 3; ++k)
    n[k] = extraordinary_valence(step.mesh, step.features, step.mesh.from(Mesh::halfedge(face, k)));
  return face_point_from(step.mesh, step.features, face, n);
}

void LabsikGreinerStencil::points(const Sqrt3Step& step, Sqrt3Points out) const {
  const Mesh& m = step.mesh;
  const Features& f = step.features;
  const auto p = m.positions();
  std::copy(p.begin(), p.end(), out.vertices.begin());
  const std::vector<int> extraordinary = extraordinary_valences(m, f);
  parallel_for_each_index(m.num_faces(), [&](std::size_t fi) {
    const FaceId face(static_cast<std::uint32_t>(fi));
    if (!step.has_face_point(face)) return;
    std::array<int, 3> n{};
    for (int k = 0; k < 3; ++k) n[k] = extraordinary[m.from(Mesh::halfedge(face, k)).idx];
    out.faces[fi] = face_point_from(m, f, face, n);
  });
}

std::array<Vec3, 2> LabsikGreinerStencil::curve_points(const Sqrt3Step& step, HalfedgeId h) const {
  // Eqs. (17)-(19): the cubic through four curve vertices at 1/3 and 2/3 of the middle edge.
  //   P_i-1 ------ P_i --x----x-- P_i+1 ------ P_i+2
  //   x at 1/3: -5/81, 20/27, 10/27, -4/81     x at 2/3: -4/81, 10/27, 20/27, -5/81
  const auto [before, a, b, after] = curve_window(step.mesh, step.features, h);
  return {(-5.0 / 81.0) * before + (20.0 / 27.0) * a + (10.0 / 27.0) * b + (-4.0 / 81.0) * after,
          (-4.0 / 81.0) * before + (10.0 / 27.0) * a + (20.0 / 27.0) * b + (-5.0 / 81.0) * after};
}

}  // namespace stlrefine
