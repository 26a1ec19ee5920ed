// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/mesh/mesh_stats.h"

#include <algorithm>
#include <limits>
#include <numeric>

namespace stlrefine {

namespace {

std::uint32_t find_root(std::vector<std::uint32_t>& parent, std::uint32_t x) {
  while (parent[x] != x) x = parent[x] = parent[parent[x]];
  return x;
}

}  // namespace

MeshStats compute_stats(const Mesh& mesh) {
  MeshStats s;
  s.vertices = mesh.num_vertices();
  s.edges = mesh.num_edges();
  s.faces = mesh.num_faces();

  constexpr double kInf = std::numeric_limits<double>::infinity();
  s.bbox_min = {kInf, kInf, kInf};
  s.bbox_max = {-kInf, -kInf, -kInf};
  for (const Vec3& p : mesh.positions()) {
    s.bbox_min = {std::min(s.bbox_min.x, p.x), std::min(s.bbox_min.y, p.y),
                  std::min(s.bbox_min.z, p.z)};
    s.bbox_max = {std::max(s.bbox_max.x, p.x), std::max(s.bbox_max.y, p.y),
                  std::max(s.bbox_max.z, p.z)};
  }

  // Components over faces, joined across twins.
  std::vector<std::uint32_t> parent(s.faces);
  std::iota(parent.begin(), parent.end(), 0u);
  for (std::uint32_t h = 0; h < mesh.num_halfedges(); ++h) {
    const HalfedgeId t = mesh.twin(HalfedgeId(h));
    if (!t.valid()) {
      ++s.boundary_edges;
      continue;
    }
    const std::uint32_t a = find_root(parent, h / 3), b = find_root(parent, t.idx / 3);
    if (a != b) parent[a] = b;
  }
  for (std::uint32_t f = 0; f < s.faces; ++f) {
    if (find_root(parent, f) == f) ++s.components;
    const auto [a, b, c] = mesh.face_vertices(FaceId(f));
    const Vec3 &pa = mesh.position(a), &pb = mesh.position(b), &pc = mesh.position(c);
    const Vec3 n = triangle_normal(pa, pb, pc);
    const double twice_area = norm(n);
    if (twice_area == 0) ++s.zero_area_faces;
    s.area += 0.5 * twice_area;
    s.volume += dot(pa, cross(pb, pc)) / 6.0;
  }

  // Boundary loops: follow each boundary half-edge to the next one around its end vertex.
  std::vector<std::uint8_t> seen(mesh.num_halfedges(), 0);
  for (std::uint32_t h = 0; h < mesh.num_halfedges(); ++h) {
    if (seen[h] || !mesh.is_boundary(HalfedgeId(h))) continue;
    ++s.boundary_loops;
    HalfedgeId g(h);
    while (g.valid() && !seen[g.idx]) {
      seen[g.idx] = 1;
      // The next boundary half-edge starts at to(g): the most clockwise outgoing one there.
      g = mesh.halfedge(mesh.to(g));
      if (!mesh.is_boundary(g)) break;
    }
  }

  s.euler_characteristic = static_cast<long long>(s.vertices) - static_cast<long long>(s.edges) +
                           static_cast<long long>(s.faces);
  s.watertight = s.boundary_edges == 0;
  if (s.watertight) {
    // Each closed orientable component has chi = 2 - 2g.
    s.genus = (2 * static_cast<long long>(s.components) - s.euler_characteristic) / 2;
  }
  return s;
}

}  // namespace stlrefine
