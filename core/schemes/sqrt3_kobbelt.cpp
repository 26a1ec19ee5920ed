// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/sqrt3_kobbelt.h"

#include <cmath>
#include <numbers>

#include "core/parallel.h"
#include "core/schemes/crease_rules.h"

namespace stlrefine {

double KobbeltRelaxation::beta(int n) {
  return (4.0 - 2.0 * std::cos(2.0 * std::numbers::pi / n)) / 9.0;
}

const std::vector<double>& KobbeltRelaxation::cached_beta() {
  static const std::vector<double> table = [] {
    std::vector<double> b(kCachedValences, 0.0);
    for (int n = 1; n < kCachedValences; ++n) b[n] = beta(n);
    return b;
  }();
  return table;
}

KobbeltRelaxation::KobbeltRelaxation() : beta_(cached_beta()) {}

Vec3 KobbeltRelaxation::displacement(const Sqrt3Step& step, VertexId v) const {
  const Mesh& m = step.mesh;
  const Vec3& p = m.position(v);
  switch (step.features.kind(v)) {
    case VertexKind::Corner:
      return {};
    case VertexKind::Crease: {
      if (!step.trisects) return {};
      const auto& ends = step.features.curve_neighbours(v);
      return curve_displacement(m.position(ends[0]), p, m.position(ends[1]));
    }
    case VertexKind::Smooth:
    case VertexKind::Dart: {
      if (m.is_isolated(v)) return {};
      Vec3 sum;
      const int n = for_each_ring_vertex_from(m, m.halfedge(v),
                                              [&](int, VertexId w) { sum += m.position(w); });
      const double b = n < kCachedValences ? beta_[n] : beta(n);
      return b * (sum * (1.0 / n) - p);
    }
  }
  return {};
}

std::array<Vec3, 2> bspline_trisection(const std::array<Vec3, 4>& w) {
  //   P_i-1 ------ P_i --x----x-- P_i+1 ------ P_i+2
  //                     1/3  2/3
  return {(w[0] + 16.0 * w[1] + 10.0 * w[2]) * (1.0 / 27.0),
          (10.0 * w[1] + 16.0 * w[2] + w[3]) * (1.0 / 27.0)};
}

Vec3 KobbeltStencil::face_point(const Sqrt3Step& step, FaceId f) const {
  const Mesh& m = step.mesh;
  const auto [a, b, c] = m.face_vertices(f);
  return (m.position(a) + m.position(b) + m.position(c)) * (1.0 / 3.0);
}

Vec3 KobbeltStencil::vertex_point(const Sqrt3Step& step, VertexId v) const {
  return step.mesh.position(v) + relaxation_.displacement(step, v);
}

void KobbeltStencil::points(const Sqrt3Step& step, Sqrt3Points out) const {
  const Mesh& m = step.mesh;
  parallel_for_each_index(m.num_vertices(), [&](std::size_t i) {
    out.vertices[i] = vertex_point(step, VertexId(static_cast<std::uint32_t>(i)));
  });
  parallel_for_each_index(m.num_faces(), [&](std::size_t f) {
    if (!step.has_face_point(FaceId(static_cast<std::uint32_t>(f)))) return;
    out.faces[f] = face_point(step, FaceId(static_cast<std::uint32_t>(f)));
  });
}

std::array<Vec3, 2> KobbeltStencil::curve_points(const Sqrt3Step& step, HalfedgeId h) const {
  return bspline_trisection(curve_window(step.mesh, step.features, h));
}

}  // namespace stlrefine
