// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Small read-only queries the tests share: finding vertices and edges by position, walking
// rings, building a Level with chosen sharp edges, comparing triangle sets.

#include <array>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "core/features/features.h"
#include "core/mesh/mesh.h"
#include "core/schemes/scheme.h"

namespace stlrefine::test {

//! The vertex at exactly position p (bit-identical), or invalid.
VertexId find_vertex(const Mesh& mesh, const Vec3& p);
//! The half-edge a -> b, or invalid.
HalfedgeId find_halfedge(const Mesh& mesh, VertexId a, VertexId b);
//! The edge between a and b, or invalid (searches both directions).
EdgeId find_edge(const Mesh& mesh, VertexId a, VertexId b);
//! Outgoing half-edges of v, ccw from the most clockwise one.
std::vector<HalfedgeId> outgoing(const Mesh& mesh, VertexId v);
//! One entry per edge at v, ccw: the neighbour and the edge. On a boundary the last entry
//! is the incoming boundary edge that closes the fan.
struct RingEntry {
  VertexId vertex;
  EdgeId edge;
};
std::vector<RingEntry> ring(const Mesh& mesh, VertexId v);

//! Id of the new vertex a 1-to-4 step puts on coarse edge e (split4_host.h: V + e).
inline VertexId edge_vertex(const Mesh& coarse, EdgeId e) {
  return VertexId(static_cast<std::uint32_t>(coarse.num_vertices() + e.idx));
}

//! A Level whose features come from detect_features(mesh, crease_angle_deg) in angle mode.
Level make_level(Mesh mesh, double crease_angle_deg = 35.0);
//! The length of the diagonal of the mesh's axis-aligned bounding box (0 without vertices).
double bbox_diagonal(const Mesh& mesh);
//! A Level whose sharp edges are exactly `sharp` (plus the boundary, which is forced).
Level make_level_with_sharp(Mesh mesh, const std::vector<std::pair<VertexId, VertexId>>& sharp);

//! Signed volume by the divergence theorem (independent of compute_stats).
double signed_volume(const Mesh& mesh);
//! Largest |coordinate| over the positions (a scale for relative tolerances).
double max_abs_coord(std::span<const Vec3> positions);

//! Triangles as position triples, each rotated so its smallest corner comes first and the
//! list sorted: equal lists mean equal oriented triangle sets. With `ignore_orientation`
//! each triple is fully sorted instead.
std::vector<std::array<Vec3, 3>> triangle_set(std::span<const Vec3> positions,
                                              std::span<const std::array<std::uint32_t, 3>> tris,
                                              bool ignore_orientation);
std::vector<std::array<Vec3, 3>> triangle_set(const Mesh& mesh, bool ignore_orientation);

//! Lexicographic order on Vec3 (for sorting and maps).
bool vec_less(const Vec3& a, const Vec3& b);

}  // namespace stlrefine::test
