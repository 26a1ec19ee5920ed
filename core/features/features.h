// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/mesh/mesh.h"

namespace stlrefine {

//! How sharp edges are found (spec section 0).
struct FeatureParams {
  //! An edge is a crease when its face normals differ by more than this (degrees,
  //! [0, 180], default 35; 180 disables crease detection; boundaries are always sharp).
  double crease_angle_deg = 35.0;

  //! \throw Error(InvalidParameter) naming the field.
  void validate() const;
};

//! Kind of a vertex by its number s of sharp edges: smooth (0), dart (1), crease (2),
//! corner (>= 3). A boundary vertex has at least two sharp (boundary) edges.
enum class VertexKind : std::uint8_t { Smooth, Dart, Crease, Corner };

const char* to_string(VertexKind kind);

//! Sharp-edge flags and vertex kinds of one mesh level. Hosts carry the flags to the
//! next level (halves of a sharp edge are sharp) and re-classify the vertices.
class Features {
 public:
  Features() = default;
  //! Classifies vertices from per-edge sharp flags (boundary edges are forced sharp).
  Features(const Mesh& mesh, BigVector<std::uint8_t> sharp_edge);
  //! For hosts that derive the next level's kinds directly. \pre consistent with a mesh.
  static Features from_parts(BigVector<std::uint8_t> sharp_edge, BigVector<VertexKind> kind,
                             BigVector<std::array<VertexId, 2>> curve_neighbours);

  bool is_sharp(EdgeId e) const { return sharp_edge_[e.idx] != 0; }
  bool is_sharp(const Mesh& mesh, HalfedgeId h) const { return is_sharp(mesh.edge(h)); }
  VertexKind kind(VertexId v) const { return kind_[v.idx]; }
  //! True for crease and corner vertices: their ring is cut into sectors by sharp edges.
  bool cuts_ring(VertexId v) const { return kind_[v.idx] >= VertexKind::Crease; }
  //! For a crease vertex, the far ends of its two sharp edges; invalid otherwise.
  const std::array<VertexId, 2>& curve_neighbours(VertexId v) const {
    return curve_neighbours_[v.idx];
  }
  //! Along the sharp polyline through the sharp edge (x, other): the curve vertex beyond x,
  //! or invalid when x ends the polyline (it is a corner or a dart).
  VertexId curve_beyond(VertexId x, VertexId other) const;

  std::span<const std::uint8_t> sharp_edges() const { return sharp_edge_; }
  std::size_t num_sharp_edges() const { return num_sharp_; }
  std::size_t count(VertexKind kind) const;

 private:
  BigVector<std::uint8_t> sharp_edge_;
  BigVector<VertexKind> kind_;
  BigVector<std::array<VertexId, 2>> curve_neighbours_;
  std::size_t num_sharp_ = 0;
};

//! Marks boundary edges and edges whose dihedral angle exceeds the crease angle.
Features detect_features(const Mesh& mesh, const FeatureParams& params);

//! Angle in degrees between the normals of the two faces at a manifold edge (0 for a
//! flat edge, boundary edges, and edges next to a zero-area face).
double dihedral_angle_deg(const Mesh& mesh, EdgeId e);

}  // namespace stlrefine
