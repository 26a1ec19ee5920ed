// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/mesh/mesh_stats.h"

#include <algorithm>
#include <limits>
#include <numeric>
#include <span>

namespace stlrefine {

namespace {

std::uint32_t find_root(std::vector<std::uint32_t>& parent, std::uint32_t x) {
  while (parent[x] != x) x = parent[x] = parent[parent[x]];
  return x;
}

}  // namespace

namespace {

constexpr std::uint32_t kNotListed = std::numeric_limits<std::uint32_t>::max();

void grow_box(Vec3& lo, Vec3& hi, const Vec3& p) {
  lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
  hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
}

// The per-body figures of the `max_bodies` largest components. `parent` is the face
// union-find, compressed to roots by the caller; the scratch is one slot per face.
std::vector<BodyStats> body_stats(const Mesh& mesh, std::vector<std::uint32_t>& parent,
                                  std::span<const std::uint32_t> loop_starts,
                                  std::size_t max_bodies) {
  const std::uint32_t faces = static_cast<std::uint32_t>(mesh.num_faces());
  // Faces per root, counted in the slot array (reused below for the list index).
  std::vector<std::uint32_t> slot(faces, 0);
  for (std::uint32_t f = 0; f < faces; ++f) ++slot[parent[f]];
  std::vector<std::uint32_t> roots;
  for (std::uint32_t f = 0; f < faces; ++f)
    if (parent[f] == f) roots.push_back(f);
  const auto larger = [&](std::uint32_t a, std::uint32_t b) {
    return slot[a] != slot[b] ? slot[a] > slot[b] : a < b;
  };
  const std::size_t listed = std::min(max_bodies, roots.size());
  std::partial_sort(roots.begin(), roots.begin() + static_cast<std::ptrdiff_t>(listed), roots.end(),
                    larger);
  roots.resize(listed);
  std::fill(slot.begin(), slot.end(), kNotListed);
  for (std::uint32_t i = 0; i < listed; ++i) slot[roots[i]] = i;

  constexpr double kInf = std::numeric_limits<double>::infinity();
  std::vector<BodyStats> bodies(listed);
  for (BodyStats& b : bodies) {
    b.bbox_min = {kInf, kInf, kInf};
    b.bbox_max = {-kInf, -kInf, -kInf};
  }
  if (listed == 0) return bodies;
  const auto body_of_face = [&](std::uint32_t f) { return slot[parent[f]]; };
  // Each vertex belongs to one body (build_mesh splits shared vertices); counted at its
  // outgoing half-edge's face.
  for (std::uint32_t v = 0; v < mesh.num_vertices(); ++v) {
    const HalfedgeId h = mesh.halfedge(VertexId(v));
    if (!h.valid()) continue;
    const std::uint32_t b = body_of_face(h.idx / 3);
    if (b == kNotListed) continue;
    ++bodies[b].vertices;
    grow_box(bodies[b].bbox_min, bodies[b].bbox_max, mesh.position(VertexId(v)));
  }
  for (std::uint32_t f = 0; f < faces; ++f) {
    const std::uint32_t b = body_of_face(f);
    if (b == kNotListed) continue;
    BodyStats& s = bodies[b];
    ++s.faces;
    const auto [va, vb, vc] = mesh.face_vertices(FaceId(f));
    const Vec3 &pa = mesh.position(va), &pb = mesh.position(vb), &pc = mesh.position(vc);
    s.area += 0.5 * norm(triangle_normal(pa, pb, pc));
    s.volume += dot(pa, cross(pb, pc)) / 6.0;
  }
  for (std::uint32_t h = 0; h < mesh.num_halfedges(); ++h) {
    const std::uint32_t b = body_of_face(h / 3);
    if (b == kNotListed) continue;
    const HalfedgeId t = mesh.twin(HalfedgeId(h));
    if (!t.valid()) {
      ++bodies[b].edges;
      ++bodies[b].boundary_edges;
    } else if (h < t.idx) {
      ++bodies[b].edges;
    }
  }
  // A loop belongs to the body of its first half-edge's face.
  for (const std::uint32_t h : loop_starts) {
    const std::uint32_t b = body_of_face(h / 3);
    if (b != kNotListed) ++bodies[b].boundary_loops;
  }
  for (BodyStats& s : bodies) {
    s.watertight = s.boundary_edges == 0;
    if (s.watertight) {
      const long long chi = static_cast<long long>(s.vertices) - static_cast<long long>(s.edges) +
                            static_cast<long long>(s.faces);
      s.genus = (2 - chi) / 2;
    }
  }
  return bodies;
}

}  // namespace

MeshStats compute_stats(const Mesh& mesh, std::size_t max_bodies) {
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
  std::vector<std::uint32_t> loop_starts;  // one half-edge of each loop, for the bodies
  for (std::uint32_t h = 0; h < mesh.num_halfedges(); ++h) {
    if (seen[h] || !mesh.is_boundary(HalfedgeId(h))) continue;
    ++s.boundary_loops;
    loop_starts.push_back(h);
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
  for (std::uint32_t f = 0; f < s.faces; ++f) parent[f] = find_root(parent, f);
  s.bodies = body_stats(mesh, parent, loop_starts, max_bodies);
  s.watertight = s.boundary_edges == 0;
  if (s.watertight) {
    // Each closed orientable component has chi = 2 - 2g.
    s.genus = (2 * static_cast<long long>(s.components) - s.euler_characteristic) / 2;
  }
  return s;
}

}  // namespace stlrefine
