// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/sqrt3_interp.h"

#include <cmath>
#include <numbers>

#include "core/error.h"
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

const std::vector<std::vector<double>>& LabsikGreinerStencil::cached_weights() {
  static const std::vector<std::vector<double>> weights = [] {
    std::vector<std::vector<double>> w(kCachedValences);
    for (int n = 3; n < kCachedValences; ++n) {
      w[n].resize(n);
      for (int i = 0; i < n; ++i) w[n][i] = extraordinary_weight(n, i);
    }
    return w;
  }();
  return weights;
}

LabsikGreinerStencil::LabsikGreinerStencil() : weights_(cached_weights()) {}

namespace {

// In a trisecting step (steps 2, 4, ...) a face along a sharp edge (it gets no face point)
// is a piece that the previous 1-to-3 split kept whole, because its sharp edge was not
// flipped. In the lattice of this level it stands for two triangles: (a, v, q) and
// (v, b, q) with the face point v = a + b - q of the (missing) face across the sharp edge
// (a, b), which the flip would have joined to q. So in these steps such a face is not part
// of the lattice: walks do not enter it (a virtual point stands in), and its apex q counts
// v as a neighbour. That makes every inner vertex next to a sharp edge regular after the
// first step, as Labsik-Greiner 5.2 states ("This will be the case for all triangles after
// the first refinement"). Read as a valence-5 extraordinary centre whose ring spans both
// pieces, q pulled face points 0.25 mm below the rim of a capped cylinder and folded faces
// there (bench/fidelity).
bool is_kept_piece(const Sqrt3Step& step, FaceId f) {
  return !step.has_face_point(f);
}

// The face across the edge of h is part of this level's lattice patch: the edge is not
// sharp and the face is not a kept piece.
bool crossable(const Sqrt3Step& step, HalfedgeId h) {
  const HalfedgeId t = step.mesh.twin(h);
  return t.valid() && !step.features.is_sharp(step.mesh.edge(h)) &&
         !is_kept_piece(step, Mesh::face(t));
}

// The tip of the triangle across the edge of h (a -> b in face (a, b, c)): the real vertex,
// or the virtual point a + b - c when that triangle is not in the patch (spec 0).
Vec3 tip(const Sqrt3Step& step, HalfedgeId h) {
  const Mesh& m = step.mesh;
  if (crossable(step, h)) return m.position(m.opposite(m.twin(h)));
  return m.position(m.from(h)) + m.position(m.to(h)) - m.position(m.opposite(h));
}

// Next outgoing half-edge around from(h) counter-clockwise (across the edge of prev(h)) or
// clockwise (across the edge of h) within the patch; invalid when the walk leaves it.
HalfedgeId ccw_in_patch(const Sqrt3Step& step, HalfedgeId h) {
  const HalfedgeId p = Mesh::prev(h);
  return crossable(step, p) ? step.mesh.twin(p) : HalfedgeId();
}
HalfedgeId cw_in_patch(const Sqrt3Step& step, HalfedgeId h) {
  return crossable(step, h) ? Mesh::next(step.mesh.twin(h)) : HalfedgeId();
}

// Outgoing h of v in face (v, p_j, p_j+1) of a trisecting step: the edge (p_j, p_j+1) is
// sharp, so the lattice has the virtual neighbour p_j + p_j+1 - v between p_j and p_j+1.
bool opposite_edge_kept(const Sqrt3Step& step, HalfedgeId h) {
  return step.trisects && step.sharp_corner[h.idx / 3] == (h.idx % 3 + 1) % 3;
}

// The extraordinary valence of a vertex as a centre of the rule of spec 3.3: its valence
// in this level's lattice (edges, plus the kept pieces around it, see is_kept_piece) when
// that is not 6 and the vertex is interior, smooth and has a whole ring; else 0. Sharp
// vertices are never centres, and neither are valence-2 ones (two faces folded onto each
// other): the rule's weights exist for n >= 3 only, and reading them at n = 2 read an
// empty table (a crash, found by fuzzing).
int extraordinary_valence(const Sqrt3Step& step, VertexId v) {
  const Mesh& m = step.mesh;
  const Features& f = step.features;
  if (f.cuts_ring(v) || m.is_isolated(v) || m.is_boundary(v)) return 0;
  int valence = 0;
  for_each_outgoing(m, v, [&](HalfedgeId h) { valence += opposite_edge_kept(step, h) ? 2 : 1; });
  return valence == 6 || valence < 3 ? 0 : valence;
}

std::vector<int> extraordinary_valences(const Sqrt3Step& step) {
  std::vector<int> n(step.mesh.num_vertices(), 0);
  parallel_for_each_index(step.mesh.num_vertices(), [&](std::size_t i) {
    n[i] = extraordinary_valence(step, VertexId(static_cast<std::uint32_t>(i)));
  });
  return n;
}

// The two far neighbours of corner a = from(h) of triangle (a, b, c): its ring vertices
// opposite b and opposite c, reached by walking two triangles around a (counter-clockwise
// past c, clockwise past b). Where the walk would leave the patch the lattice point
// 2a - b (resp. 2a - c) stands in.
//
//         c ---- tip
//        / \    /
//   far_b ---- a ---- b         far_b = opposite b (2a - b),  far_c = opposite c (2a - c)
//      /    \ /  \   /
//   ...    far_c -- tip
Vec3 far_neighbours(const Sqrt3Step& step, HalfedgeId h) {
  const Mesh& m = step.mesh;
  const Vec3& a = m.position(m.from(h));
  HalfedgeId ccw = ccw_in_patch(step, h);
  if (ccw.valid()) ccw = ccw_in_patch(step, ccw);
  HalfedgeId cw = cw_in_patch(step, h);
  if (cw.valid()) cw = cw_in_patch(step, cw);
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
Vec3 regular_point(const Sqrt3Step& step, FaceId face) {
  Vec3 a, b, c;
  for (int k = 0; k < 3; ++k) {
    const HalfedgeId h = Mesh::halfedge(face, k);
    a += step.mesh.position(step.mesh.from(h));
    b += tip(step, h);
    c += far_neighbours(step, h);
  }
  return LabsikGreinerStencil::kCorner * a + LabsikGreinerStencil::kTip * b +
         LabsikGreinerStencil::kFar * c;
}

}  // namespace

Vec3 LabsikGreinerStencil::extraordinary_point(const Sqrt3Step& step, HalfedgeId h, int n) const {
  //        p2 ---- p1
  //       /  \ q  /  \       q = 2/3 p + sum_i alpha_i p_i, ring counted from p0 = to(h)
  //    p3 ---- p ---- p0     towards p1 (the triangle's other corner); in a trisecting
  //       \  /    \  /       step a virtual p_j + p_j+1 - p follows p_j where the edge
  //        .. ---- p_n-1     (p_j, p_j+1) is sharp (see is_kept_piece)
  const Mesh& m = step.mesh;
  const Vec3& centre = m.position(m.from(h));
  Vec3 sum = kCentre * centre;
  const double* cached = n < kCachedValences ? weights_[n].data() : nullptr;
  auto weight = [&](int i) { return cached ? cached[i] : extraordinary_weight(n, i); };
  int i = 0;
  HalfedgeId g = h;
  do {
    const Vec3& p = m.position(m.to(g));
    sum += weight(i++) * p;
    if (opposite_edge_kept(step, g)) sum += weight(i++) * (p + m.position(m.opposite(g)) - centre);
    g = m.ccw_rotated(g);
  } while (g.valid() && g != h && i < n);
  if (i != n || g != h) throw Error(ErrorCode::Internal, "sqrt3_ring", "sqrt3-interp: ring walk");
  return sum;
}

Vec3 LabsikGreinerStencil::face_point_from(const Sqrt3Step& step, FaceId face,
                                           const std::array<int, 3>& extraordinary) const {
  // Several extraordinary corners (coarsest level only): the average of their rules.
  Vec3 sum;
  int centres = 0;
  for (int k = 0; k < 3; ++k) {
    if (extraordinary[k] == 0) continue;
    sum += extraordinary_point(step, Mesh::halfedge(face, k), extraordinary[k]);
    ++centres;
  }
  return centres == 0 ? regular_point(step, face) : centres == 1 ? sum : sum * (1.0 / centres);
}

Vec3 LabsikGreinerStencil::face_point(const Sqrt3Step& step, FaceId face) const {
  std::array<int, 3> n{};
  for (int k = 0; k < 3; ++k)
    n[k] = extraordinary_valence(step, step.mesh.from(Mesh::halfedge(face, k)));
  return face_point_from(step, face, n);
}

void LabsikGreinerStencil::points(const Sqrt3Step& step, Sqrt3Points out) const {
  const Mesh& m = step.mesh;
  const auto p = m.positions();
  std::copy(p.begin(), p.end(), out.vertices.begin());
  const std::vector<int> extraordinary = extraordinary_valences(step);
  parallel_for_each_index(m.num_faces(), [&](std::size_t fi) {
    const FaceId face(static_cast<std::uint32_t>(fi));
    if (!step.has_face_point(face)) return;
    std::array<int, 3> n{};
    for (int k = 0; k < 3; ++k) n[k] = extraordinary[m.from(Mesh::halfedge(face, k)).idx];
    out.faces[fi] = face_point_from(step, face, n);
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
