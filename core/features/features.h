// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "core/mesh/mesh.h"

namespace stlrefine {

//! How sharp edges are found: from what the geometry says (the default), or by the angle
//! alone (what a user who gives `crease_angle` asks for).
enum class CreaseMode : std::uint8_t {
  //! An edge is a crease when its dihedral angle stands out against the curvature of the
  //! faces on both sides across it (see detect_features): a coarse smooth surface, whose
  //! dihedrals are all alike, has none; a plane meeting a curved fillet at a few degrees is
  //! one. crease_angle_deg is not used.
  Auto,
  //! An edge is a crease when its face normals differ by more than crease_angle_deg.
  Angle,
};

const char* to_string(CreaseMode mode);

//! How sharp edges are found (spec section 0). Boundaries are always sharp.
struct FeatureParams {
  //! Angle mode: an edge is a crease when its face normals differ by more than this
  //! (degrees, [0, 180], default 35; 180 disables crease detection).
  double crease_angle_deg = 35.0;
  //! Auto by default; the API's `crease_angle=<degrees>` selects Angle, `crease_angle=auto`
  //! (or leaving it out) Auto.
  CreaseMode crease_mode = CreaseMode::Auto;

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

//! Marks boundary edges, and creases as params.crease_mode says.
//!
//! Auto mode (issue 17 item 5). A coarse smooth surface has similar dihedrals on all edges
//! around; a plane has none. A face's "bend" seen from an edge is the largest dihedral of
//! its two other edges and of the edges beyond those that do not touch the edge (across a
//! split quad: the parallel edge), always-sharp edges left out. An edge is a crease when
//! - its dihedral is at least kAutoCreaseAlwaysDeg; or
//! - both of its faces are planar (as below) and it is at least kAutoCreasePlanesDeg; or
//! - exactly one of its two faces is planar (across one of its other edges a neighbour
//!   within kAutoCreaseFlatDeg, and no other bend there below kAutoCreasePlanesDeg), that
//!   face's planar region is a plane (below kAutoCreasePlanesDeg: its area at least the
//!   square of kAutoCreasePlaneSize, and its width across the edge (area / edge length) at
//!   least kAutoCreasePlaneWidth, times the other face's height over the edge; the flat
//!   polygon capping a coarse sphere, a strip of a zipped cylinder side and one facet of a
//!   tessellated arc are chords, not planes) and the dihedral exceeds half the largest
//!   dihedral of the curved face's other two edges (a tangent-continuous plane meets chords
//!   of a fillet at half their angle) by kAutoCreaseExcessDeg: a plane meeting a curved
//!   region at a shallow angle; or
//! - both faces are planar, only one of them a plane, and the dihedral exceeds half the
//!   other's bend by kAutoCreaseExcessDeg (a plane meeting a planar strip of a fillet);
//!   where these two planar-side rules (below kAutoCreasePlanesDeg) hold, the surface must
//!   also not be smooth across the edge: in the section across it, the tangents of its two
//!   sides at the edge (section_tangent of the vertices beside the edge on each side)
//!   differ by at least kAutoCreaseExcessDeg. A plane meeting a zipped fillet tangentially,
//!   whose twisted zipper triangles bend anyhow, and a row of a uniformly faceted surface,
//!   whose "plane" is one facet, are smooth; a plane meeting a fillet at a crease is not; or
//! - it stands out: at least kAutoCreaseRatio times and kAutoCreaseStandOutDeg above the
//!   bend of both faces, and at both of its ends a sharp edge continues it turning by less
//!   than kAutoCreaseTurnDeg (a crease is a chain); or both faces are planar and bend
//!   nowhere else (two walls of an extruded polygon between the steep edges that cap them:
//!   no chain needed).
//! Then gaps in chains are filled: an edge continued (as above) by sharp edges at both
//! ends, bending at least kAutoCreaseGapRatio times as much as they do and kAutoCreaseRatio
//! times its faces' bend, is sharp too. Last, an edge found by a rule other than the steep
//! ones that meets no other sharp or boundary edge at either end is dropped (a crease runs
//! until it meets another feature); so is one found by the first two (steep) rules that
//! meets none and bends less than kAutoCreaseRatio times its faces' bend (a sliver's fold
//! on a coarse zipped torus).
Features detect_features(const Mesh& mesh, const FeatureParams& params);

//! Auto mode's thresholds (degrees, and a ratio), see detect_features.
inline constexpr double kAutoCreaseExcessDeg = 4.0;
inline constexpr double kAutoCreaseRatio = 3.0;
inline constexpr double kAutoCreaseStandOutDeg = 15.0;
inline constexpr double kAutoCreaseAlwaysDeg = 65.0;
inline constexpr double kAutoCreaseTurnDeg = 45.0;
inline constexpr double kAutoCreaseFlatDeg = 0.1;
inline constexpr double kAutoCreasePlanesDeg = 35.0;
inline constexpr double kAutoCreaseGapRatio = 0.5;
inline constexpr double kAutoCreasePlaneSize = 2.0;
inline constexpr double kAutoCreasePlaneWidth = 5.0;

//! A vertex beside an edge in the section across it: d > 0 its distance from the edge's
//! line across it, h its height below a reference plane through the edge.
struct SectionPoint {
  double d = 0;
  double h = 0;
};

//! The tangent of a surface at an edge, in the section across it, from vertices on one side
//! (auto mode's smoothness test): its elevation atan(h / d) in radians, of the
//! least-squares circle through the edge and the points (exact on a cylinder or a fillet
//! parallel to the edge: 0 where it is tangent to the reference plane, however its chords
//! are triangulated), and that circle's radius. When the points do not fix a circle (they
//! lie in directions within kSectionSpreadDeg of each other, or at distances within
//! kSectionDistanceSpread of the farthest's), the mean of their directions (the chord) and
//! no radius (HUGE_VAL), with `fitted` false.
struct SectionTangent {
  double elevation = 0;
  double radius = HUGE_VAL;
  bool fitted = false;
};
//! nullopt when there is no point.
std::optional<SectionTangent> section_tangent(std::span<const SectionPoint> points);

inline constexpr double kSectionSpreadDeg = 1.0;
inline constexpr double kSectionDistanceSpread = 0.2;

//! Angle in degrees between the normals of the two faces at a manifold edge (0 for a
//! flat edge, boundary edges, and edges next to a zero-area face).
double dihedral_angle_deg(const Mesh& mesh, EdgeId e);

}  // namespace stlrefine
