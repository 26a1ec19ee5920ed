// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/mesh/mesh.h"

#include <string>

#include "core/error.h"

namespace stlrefine {

namespace {

// Edge ids in half-edge order: an edge is numbered when its first half-edge is met
// (a boundary half-edge, or the lower-numbered half of a twin pair).
void derive_edges(const BigVector<HalfedgeId>& twin, BigVector<EdgeId>& edge_of,
                  BigVector<HalfedgeId>& edge_halfedge) {
  edge_of.assign(twin.size(), EdgeId());
  edge_halfedge.clear();
  edge_halfedge.reserve(twin.size() / 2 + 1);
  for (std::uint32_t h = 0; h < twin.size(); ++h) {
    const HalfedgeId t = twin[h];
    if (t.valid() && t.idx < h) {
      edge_of[h] = edge_of[t.idx];
      continue;
    }
    edge_of[h] = EdgeId(static_cast<std::uint32_t>(edge_halfedge.size()));
    edge_halfedge.push_back(HalfedgeId(h));
  }
}

// Most clockwise outgoing half-edge per vertex: any outgoing one, then rotate clockwise
// until a boundary is hit or the fan closes.
BigVector<HalfedgeId> derive_vertex_halfedges(std::size_t num_vertices,
                                              const BigVector<VertexId>& corner_vertex,
                                              const BigVector<HalfedgeId>& twin) {
  BigVector<HalfedgeId> vh(num_vertices);
  for (std::uint32_t h = 0; h < corner_vertex.size(); ++h) {
    HalfedgeId& slot = vh[corner_vertex[h].idx];
    // Prefer an outgoing boundary half-edge: it is the most clockwise one of its fan.
    if (!slot.valid() || !twin[h].valid()) slot = HalfedgeId(h);
  }
  return vh;
}

}  // namespace

Mesh Mesh::from_parts(BigVector<Vec3> positions, BigVector<VertexId> corner_vertex,
                      BigVector<HalfedgeId> twin) {
  BigVector<EdgeId> edge_of;
  BigVector<HalfedgeId> edge_halfedge;
  derive_edges(twin, edge_of, edge_halfedge);
  auto vh = derive_vertex_halfedges(positions.size(), corner_vertex, twin);
  return from_parts_with_edges(std::move(positions), std::move(corner_vertex), std::move(twin),
                               std::move(edge_of), std::move(edge_halfedge), std::move(vh));
}

Mesh Mesh::from_parts_with_edges(BigVector<Vec3> positions, BigVector<VertexId> corner_vertex,
                                 BigVector<HalfedgeId> twin, BigVector<EdgeId> edge_of,
                                 BigVector<HalfedgeId> edge_halfedge,
                                 BigVector<HalfedgeId> vertex_halfedge) {
  if (corner_vertex.size() % 3 != 0 || twin.size() != corner_vertex.size() ||
      edge_of.size() != corner_vertex.size() || vertex_halfedge.size() != positions.size()) {
    throw Error(ErrorCode::Internal, "mesh_arrays", "mesh arrays have inconsistent sizes");
  }
  if (corner_vertex.size() / 3 >= HalfedgeId::kInvalid / 3 ||
      positions.size() >= VertexId::kInvalid) {
    throw Error(ErrorCode::BudgetExceeded, "index_overflow", "mesh too large for 32-bit indices");
  }
  Mesh m;
  m.positions_ = std::move(positions);
  m.corner_vertex_ = std::move(corner_vertex);
  m.twin_ = std::move(twin);
  m.edge_of_ = std::move(edge_of);
  m.edge_halfedge_ = std::move(edge_halfedge);
  m.vertex_halfedge_ = std::move(vertex_halfedge);
  return m;
}

Vec3 Mesh::face_normal(FaceId f) const {
  const auto [a, b, c] = face_vertices(f);
  return triangle_normal(position(a), position(b), position(c));
}

int Mesh::valence(VertexId v) const {
  int n = 0;
  HalfedgeId last;
  for_each_outgoing(*this, v, [&](HalfedgeId h) {
    ++n;
    last = h;
  });
  // An open fan has one more edge than faces: the incoming boundary edge that closes it.
  if (last.valid() && is_boundary(v)) ++n;
  return n;
}

std::string Mesh::check_invariants() const {
  const std::size_t nh = num_halfedges();
  for (std::uint32_t h = 0; h < nh; ++h) {
    const HalfedgeId hh(h);
    const VertexId v = from(hh);
    if (!v.valid() || v.idx >= num_vertices())
      return "half-edge " + std::to_string(h) + ": bad vertex";
    if (from(hh) == to(hh)) return "half-edge " + std::to_string(h) + ": degenerate";
    const HalfedgeId t = twin(hh);
    if (t.valid()) {
      if (t.idx >= nh || twin(t) != hh)
        return "half-edge " + std::to_string(h) + ": twin not symmetric";
      if (from(t) != to(hh) || to(t) != from(hh))
        return "half-edge " + std::to_string(h) + ": twin not opposite";
    }
    const EdgeId e = edge(hh);
    if (!e.valid() || e.idx >= num_edges()) return "half-edge " + std::to_string(h) + ": bad edge";
    const HalfedgeId eh = halfedge(e);
    if (eh != hh && eh != t) return "half-edge " + std::to_string(h) + ": edge mismatch";
  }
  for (std::uint32_t e = 0; e < num_edges(); ++e) {
    const HalfedgeId h = edge_halfedge_[e];
    if (edge(h) != EdgeId(e)) return "edge " + std::to_string(e) + ": half-edge mismatch";
  }
  // Every vertex is one fan: walking from its stored half-edge visits all its corners.
  std::vector<std::uint32_t> corners(num_vertices(), 0);
  for (std::uint32_t h = 0; h < nh; ++h) ++corners[corner_vertex_[h].idx];
  for (std::uint32_t v = 0; v < num_vertices(); ++v) {
    const HalfedgeId start = vertex_halfedge_[v];
    if (!start.valid()) {
      if (corners[v] != 0) return "vertex " + std::to_string(v) + ": corners but no half-edge";
      continue;
    }
    if (from(start) != VertexId(v))
      return "vertex " + std::to_string(v) + ": half-edge not outgoing";
    std::uint32_t seen = 0;
    HalfedgeId h = start;
    do {
      ++seen;
      h = ccw_rotated(h);
    } while (h.valid() && h != start && seen <= corners[v]);
    // An open fan must start at its boundary half-edge, or the walk misses faces.
    if (!h.valid() && !is_boundary(start))
      return "vertex " + std::to_string(v) + ": not the most clockwise half-edge";
    if (seen != corners[v]) return "vertex " + std::to_string(v) + ": more than one fan";
  }
  return {};
}

std::size_t Mesh::memory_bytes() const {
  return positions_.capacity() * sizeof(Vec3) + corner_vertex_.capacity() * sizeof(VertexId) +
         twin_.capacity() * sizeof(HalfedgeId) + edge_of_.capacity() * sizeof(EdgeId) +
         edge_halfedge_.capacity() * sizeof(HalfedgeId) +
         vertex_halfedge_.capacity() * sizeof(HalfedgeId);
}

}  // namespace stlrefine
