// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/features/features.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "core/error.h"
#include "core/parallel.h"

namespace stlrefine {

void FeatureParams::validate() const {
  require_in_range("crease_angle", crease_angle_deg, 0.0, 180.0);
}

const char* to_string(VertexKind kind) {
  switch (kind) {
    case VertexKind::Smooth:
      return "smooth";
    case VertexKind::Dart:
      return "dart";
    case VertexKind::Crease:
      return "crease";
    case VertexKind::Corner:
      return "corner";
  }
  return "smooth";
}

Features::Features(const Mesh& mesh, BigVector<std::uint8_t> sharp_edge)
    : sharp_edge_(std::move(sharp_edge)) {
  if (sharp_edge_.size() != mesh.num_edges())
    throw Error(ErrorCode::Internal, "feature_size", "sharp flags do not match the edges");
  for (std::size_t e = 0; e < sharp_edge_.size(); ++e) {
    if (mesh.is_boundary(EdgeId(e))) sharp_edge_[e] = 1;
    num_sharp_ += sharp_edge_[e];
  }
  const std::size_t nv = mesh.num_vertices();
  kind_.resize(nv);
  curve_neighbours_.resize(nv);
  parallel_for_each_index(nv, [&](std::size_t i) {
    const VertexId v(static_cast<std::uint32_t>(i));
    int sharp = 0;
    std::array<VertexId, 2> ends{};
    auto note = [&](HalfedgeId h, VertexId far) {
      if (!is_sharp(mesh.edge(h))) return;
      if (sharp < 2) ends[sharp] = far;
      ++sharp;
    };
    HalfedgeId last;
    for_each_outgoing(mesh, v, [&](HalfedgeId h) {
      note(h, mesh.to(h));
      last = h;
    });
    // The incoming boundary half-edge closing an open fan is an edge of v too.
    if (last.valid() && mesh.is_boundary(v)) note(Mesh::prev(last), mesh.from(Mesh::prev(last)));
    kind_[i] = sharp == 0   ? VertexKind::Smooth
               : sharp == 1 ? VertexKind::Dart
               : sharp == 2 ? VertexKind::Crease
                            : VertexKind::Corner;
    curve_neighbours_[i] = sharp == 2 ? ends : std::array<VertexId, 2>{};
  });
}

Features Features::from_parts(BigVector<std::uint8_t> sharp_edge, BigVector<VertexKind> kind,
                              BigVector<std::array<VertexId, 2>> curve_neighbours) {
  Features f;
  f.sharp_edge_ = std::move(sharp_edge);
  f.kind_ = std::move(kind);
  f.curve_neighbours_ = std::move(curve_neighbours);
  f.num_sharp_ = static_cast<std::size_t>(
      std::count_if(f.sharp_edge_.begin(), f.sharp_edge_.end(), [](std::uint8_t s) { return s; }));
  return f;
}

VertexId Features::curve_beyond(VertexId x, VertexId other) const {
  if (kind(x) != VertexKind::Crease) return VertexId();
  const auto& n = curve_neighbours_[x.idx];
  // Both sharp edges of x may end at `other` (a two-edge loop): then there is no distinct
  // vertex beyond and the end condition applies.
  if (n[0] == other) return n[1] == other ? VertexId() : n[1];
  if (n[1] == other) return n[0];
  return VertexId();  // (x, other) is not one of x's sharp edges
}

std::size_t Features::count(VertexKind k) const {
  return static_cast<std::size_t>(std::count(kind_.begin(), kind_.end(), k));
}

double dihedral_angle_deg(const Mesh& mesh, EdgeId e) {
  const HalfedgeId h = mesh.halfedge(e);
  const HalfedgeId t = mesh.twin(h);
  if (!t.valid()) return 0.0;
  const Vec3 n1 = normalized(mesh.face_normal(Mesh::face(h)));
  const Vec3 n2 = normalized(mesh.face_normal(Mesh::face(t)));
  if (n1 == Vec3{} || n2 == Vec3{}) return 0.0;  // no direction on a zero-area face
  // atan2 of |n1 x n2| and n1.n2 is accurate for small and large angles alike.
  return std::atan2(norm(cross(n1, n2)), dot(n1, n2)) * 180.0 / std::numbers::pi;
}

Features detect_features(const Mesh& mesh, const FeatureParams& params) {
  params.validate();
  BigVector<std::uint8_t> sharp(mesh.num_edges());
  // angle > theta  <=>  n1.n2 < cos(theta) |n1| |n2|: no normalisation, no atan2.
  const double cos_limit = std::cos(params.crease_angle_deg * std::numbers::pi / 180.0);
  const bool disabled = params.crease_angle_deg >= 180.0;
  // Each face's normal once (an inner face has three edges, so the per-edge test would
  // compute it three times); the same values, so the same flags.
  BigVector<Vec3> normal(disabled ? 0 : mesh.num_faces());
  if (!disabled)
    parallel_for_each_index(mesh.num_faces(), [&](std::size_t f) {
      normal[f] = mesh.face_normal(FaceId(static_cast<std::uint32_t>(f)));
    });
  parallel_for_each_index(mesh.num_edges(), [&](std::size_t e) {
    const HalfedgeId h = mesh.halfedge(EdgeId(static_cast<std::uint32_t>(e)));
    const HalfedgeId t = mesh.twin(h);
    sharp[e] = 0;
    if (!t.valid() || disabled) return;
    const Vec3& n1 = normal[Mesh::face(h).idx];
    const Vec3& n2 = normal[Mesh::face(t).idx];
    const double scale = std::sqrt(dot(n1, n1) * dot(n2, n2));
    sharp[e] = scale > 0 && dot(n1, n2) < cos_limit * scale;
  });
  return Features(mesh, std::move(sharp));
}

}  // namespace stlrefine
