// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "primitives/chordal.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace stlrefine::primitives {

std::vector<double> chordal_bounds(const Mesh& mesh, const Features& features, double floor) {
  const std::size_t nf = mesh.num_faces();
  std::vector<Vec3> normal(nf);
  for (std::size_t f = 0; f < nf; ++f) {
    const Vec3 n = mesh.face_normal(FaceId(static_cast<std::uint32_t>(f)));
    normal[f] = norm(n) > 0 ? normalized(n) : Vec3{};
  }
  auto stops = [&](HalfedgeId h) { return mesh.is_boundary(h) || features.is_sharp(mesh.edge(h)); };
  // The largest |n . t| over the faces of f's sector at the corner h leaves (the faces
  // around it reached from f without crossing a sharp or boundary edge).
  auto sector_tilt = [&](HalfedgeId h0, const Vec3& t) {
    const FaceId f = Mesh::face(h0);
    double m = std::abs(dot(normal[f.idx], t));
    HalfedgeId h = h0;
    for (std::size_t guard = 0; guard < 4096; ++guard) {
      const HalfedgeId in = Mesh::prev(h);
      if (stops(in)) break;
      h = mesh.twin(in);
      if (Mesh::face(h) == f) break;
      m = std::max(m, std::abs(dot(normal[Mesh::face(h).idx], t)));
    }
    h = h0;
    for (std::size_t guard = 0; guard < 4096; ++guard) {
      if (stops(h)) break;
      h = Mesh::next(mesh.twin(h));
      if (Mesh::face(h) == f) break;
      m = std::max(m, std::abs(dot(normal[Mesh::face(h).idx], t)));
    }
    return std::min(m, 1.0);
  };
  std::vector<double> bound(nf, floor);
  for (std::size_t f = 0; f < nf; ++f) {
    const FaceId face(static_cast<std::uint32_t>(f));
    double worst = 0;
    for (int k = 0; k < 3; ++k) {
      const HalfedgeId h = Mesh::halfedge(face, k);
      const Vec3 d = mesh.position(mesh.to(h)) - mesh.position(mesh.from(h));
      const double len = norm(d);
      if (!(len > 0)) continue;
      const Vec3 t = d * (1.0 / len);
      // From the edge's start, the sector of f there; from its end, the sector of f at the
      // end (the halfedge of f leaving it).
      double tilt_a = sector_tilt(h, t), tilt_b = sector_tilt(Mesh::next(h), t);
      // A crease is also a chord of the curve the faces across it follow (an annulus cap's
      // rim curves in the cap's own plane: only the wall's normals show it).
      if (!mesh.is_boundary(h) && features.is_sharp(mesh.edge(h))) {
        const HalfedgeId w = mesh.twin(h);  // from b to a
        tilt_a = std::max(tilt_a, sector_tilt(Mesh::next(w), t));
        tilt_b = std::max(tilt_b, sector_tilt(w, t));
      }
      const double turn = std::min(std::asin(tilt_a) + std::asin(tilt_b), std::numbers::pi);
      worst = std::max(worst, (len / 2) * std::tan(turn / 4));
    }
    if (std::isfinite(worst)) bound[f] = std::max(bound[f], kCentroidOverEdge * worst);
  }
  return bound;
}

}  // namespace stlrefine::primitives
