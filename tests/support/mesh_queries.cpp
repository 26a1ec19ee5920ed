// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "tests/support/mesh_queries.h"

#include <algorithm>
#include <cmath>

namespace stlrefine::test {

VertexId find_vertex(const Mesh& mesh, const Vec3& p) {
  for (std::uint32_t v = 0; v < mesh.num_vertices(); ++v)
    if (mesh.position(VertexId(v)) == p) return VertexId(v);
  return VertexId();
}

HalfedgeId find_halfedge(const Mesh& mesh, VertexId a, VertexId b) {
  // Scan all half-edges rather than walk the ring: this must work even if the ring walk
  // under test is broken.
  for (std::uint32_t h = 0; h < mesh.num_halfedges(); ++h)
    if (mesh.from(HalfedgeId(h)) == a && mesh.to(HalfedgeId(h)) == b) return HalfedgeId(h);
  return HalfedgeId();
}

EdgeId find_edge(const Mesh& mesh, VertexId a, VertexId b) {
  HalfedgeId h = find_halfedge(mesh, a, b);
  if (!h.valid()) h = find_halfedge(mesh, b, a);
  return h.valid() ? mesh.edge(h) : EdgeId();
}

std::vector<HalfedgeId> outgoing(const Mesh& mesh, VertexId v) {
  std::vector<HalfedgeId> out;
  for_each_outgoing(mesh, v, [&](HalfedgeId h) { out.push_back(h); });
  return out;
}

std::vector<RingEntry> ring(const Mesh& mesh, VertexId v) {
  std::vector<RingEntry> out;
  const auto outs = outgoing(mesh, v);
  for (HalfedgeId h : outs) out.push_back({mesh.to(h), mesh.edge(h)});
  if (!outs.empty() && mesh.is_boundary(v)) {
    const HalfedgeId closing = Mesh::prev(outs.back());  // incoming, no twin
    out.push_back({mesh.from(closing), mesh.edge(closing)});
  }
  return out;
}

double bbox_diagonal(const Mesh& mesh) {
  if (mesh.num_vertices() == 0) return 0;
  Vec3 lo = mesh.position(VertexId(0)), hi = lo;
  for (const Vec3& p : mesh.positions()) {
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
  }
  return distance(lo, hi);
}

Level make_level(Mesh mesh, double crease_angle_deg) {
  Level level;
  level.mesh = std::move(mesh);
  FeatureParams params;
  params.crease_angle_deg = crease_angle_deg;
  params.crease_mode = CreaseMode::Angle;
  level.features = detect_features(level.mesh, params);
  return level;
}

Level make_level_with_sharp(Mesh mesh, const std::vector<std::pair<VertexId, VertexId>>& sharp) {
  Level level;
  level.mesh = std::move(mesh);
  BigVector<std::uint8_t> flags(level.mesh.num_edges(), 0);
  for (const auto& [a, b] : sharp) {
    const EdgeId e = find_edge(level.mesh, a, b);
    if (e.valid()) flags[e.idx] = 1;
  }
  level.features = Features(level.mesh, std::move(flags));
  return level;
}

double signed_volume(const Mesh& mesh) {
  double six_v = 0;
  for (std::uint32_t f = 0; f < mesh.num_faces(); ++f) {
    const auto [a, b, c] = mesh.face_vertices(FaceId(f));
    six_v += dot(mesh.position(a), cross(mesh.position(b), mesh.position(c)));
  }
  return six_v / 6.0;
}

double max_abs_coord(std::span<const Vec3> positions) {
  double m = 0;
  for (const Vec3& p : positions) m = std::max({m, std::abs(p.x), std::abs(p.y), std::abs(p.z)});
  return m;
}

bool vec_less(const Vec3& a, const Vec3& b) {
  if (a.x != b.x) return a.x < b.x;
  if (a.y != b.y) return a.y < b.y;
  return a.z < b.z;
}

std::vector<std::array<Vec3, 3>> triangle_set(std::span<const Vec3> positions,
                                              std::span<const std::array<std::uint32_t, 3>> tris,
                                              bool ignore_orientation) {
  std::vector<std::array<Vec3, 3>> out;
  out.reserve(tris.size());
  for (const auto& t : tris) {
    std::array<Vec3, 3> p = {positions[t[0]], positions[t[1]], positions[t[2]]};
    if (ignore_orientation) {
      std::sort(p.begin(), p.end(), vec_less);
    } else {
      const auto first = std::min_element(p.begin(), p.end(), vec_less);
      std::rotate(p.begin(), first, p.end());
    }
    out.push_back(p);
  }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) {
    for (int k = 0; k < 3; ++k) {
      if (vec_less(a[k], b[k])) return true;
      if (vec_less(b[k], a[k])) return false;
    }
    return false;
  });
  return out;
}

std::vector<std::array<Vec3, 3>> triangle_set(const Mesh& mesh, bool ignore_orientation) {
  std::vector<std::array<std::uint32_t, 3>> tris;
  for (std::uint32_t f = 0; f < mesh.num_faces(); ++f) {
    const auto [a, b, c] = mesh.face_vertices(FaceId(f));
    tris.push_back({a.idx, b.idx, c.idx});
  }
  return triangle_set(mesh.positions(), tris, ignore_orientation);
}

}  // namespace stlrefine::test
