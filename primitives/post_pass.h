// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "core/features/features.h"
#include "core/mesh/mesh.h"
#include "primitives/regions.h"
#include "primitives/smooth_pull.h"

namespace stlrefine::primitives {

//! The normal change over which an output face counts as turned (issue 17: a fold or a
//! visible ridge).
inline constexpr double kFoldDegrees = 60;

//! What the post-pass does after refinement.
struct PostPassParams {
  //! Move new vertices onto the recognised primitives (primitives=auto).
  bool snap = true;
  //! The deviation bound (mm) every output vertex is pulled back within, towards its
  //! closest point on the input surface:
  //! - nullopt: the default, the input's own chordal error at the vertex: chordal_bounds
  //!   (primitives/chordal.h) of its closest input face, at least 1e-12 of the diagonal (and
  //!   the recognition tolerance on a recognised region); a vertex snapped onto a primitive
  //!   is held to the largest such bound of the recognised faces near it (a rim vertex lies
  //!   on the side's circle, next to the cap's flat faces), and a snap that would end
  //!   farther than that is refused;
  //! - 0: off;
  //! - > 0: this bound for every output vertex, snapped or not.
  std::optional<double> max_deviation;
  //! The refined mesh's features (RefineResult::features): a new vertex goes onto the
  //! intersection curve of two primitives only when it is a crease vertex there. Without
  //! them any vertex near an input crease may (fan slivers of a cap along its rim then put
  //! cap vertices on the rim and turn faces over).
  const Features* refined_features = nullptr;
  //! Snap only vertices whose faces all voted for recognised regions: one beside a face
  //! of no region (a plane's vertex next to a fillet no primitive fits) stays where the
  //! scheme put it. For the snaps between levels, which the next level builds on.
  bool snap_inside_regions_only = false;
  //! How vertices past the bound are pulled back: as a sheet (smooth_pull).
  SmoothPullParams pull;
};

//! What the post-pass did, for the report.
struct PostPassReport {
  std::size_t vertices_checked = 0;  //!< output vertices that are not input vertices
  std::size_t snapped = 0;           //!< moved onto one primitive
  std::size_t snapped_to_curve = 0;  //!< moved onto the intersection of two primitives
  std::size_t snap_refused = 0;      //!< whose snap would have moved them too far
  //! Snaps taken back because they turned a face more than kFoldDegrees from the input, or
  //! collapsed it (two corners at one point: it has no normal, and worst_normal_change_deg
  //! and faces_turned_over_60_deg skip it).
  std::size_t snaps_reverted = 0;
  double max_snap_move = 0;  //!< mm
  //! Moved by the deviation bound: the vertices past it and the sheet around them
  //! (smooth_pull).
  std::size_t pulled_back = 0;
  double max_pull_back = 0;        //!< mm
  std::size_t past_bound = 0;      //!< new vertices past their bound before the pull
  std::size_t pulled_alone = 0;    //!< of them, pulled alone after smooth_pull's rounds
  double max_distance_before = 0;  //!< from the input surface, before this pass (mm)
  double max_distance = 0;         //!< from the input surface, after it (mm)
  double max_bound = 0;        //!< the largest deviation bound applied to a vertex (mm); 0 = off
  bool default_bound = false;  //!< the bound is the local default
  //! The largest angle between an output face's normal and the input's (degrees), after the
  //! pass: per output face, the best agreeing of its corners' closest input faces and, when
  //! none agrees within kFoldDegrees, of the input faces within the face's longest edge of
  //! its centroid (beyond the closest one's distance).
  double worst_normal_change_deg = 0;
  //! Output faces whose normal change is over kFoldDegrees (a fold or a visible ridge).
  std::size_t faces_turned_over_60_deg = 0;
  //! apply_guarded: > 0 when the snaps turned this many faces over kFoldDegrees, more than
  //! the deviation bound alone, and were withdrawn (the figures are then the bound's).
  std::size_t withdrawn_turned_faces = 0;
  double seconds = 0;         //!< apply()
  double detect_seconds = 0;  //!< region detection and the surface's construction (the caller's)
};

//! The input surface as the post-pass needs it after the input mesh is gone: its triangles
//! (a CGAL AABB tree, built once), their regions and default deviation bounds (see
//! predict_bytes for the memory it holds).
class InputSurface {
 public:
  //! Keeps what it needs of mesh (positions and triangles), regions (may be null: no
  //! snapping) and the per-face default bounds from features.
  InputSurface(const Mesh& mesh, const Features& features, const RegionMap* regions);
  ~InputSurface();
  InputSurface(const InputSurface&) = delete;
  InputSurface& operator=(const InputSurface&) = delete;

  //! Snaps the new vertices of `refined` (those that are not, bit for bit, input vertices)
  //! onto their recognised primitives, then pulls every new vertex within the deviation
  //! bound of the input surface. Input vertices are never moved. Parallel (TBB).
  //! Which region a new vertex derives from: its nearest input faces (those within a quarter of
  //! its longest incident edge beyond its distance to the input), each incident refined face taking
  //! the one whose normal it agrees with best (the nearest among equals); one region: its
  //! primitive; two: their intersection curve (or, if the curve is not reached, the plane among
  //! them, so planes stay planar); three or more: none. A vertex within 15% of its longest edge of
  //! an input crease between two recognised regions goes onto their curve first. A snap is refused
  //! when it would move a vertex farther than half its longest incident edge, or farther from the
  //! input than the bound it is held to (see PostPassParams::max_deviation). Every new vertex
  //! ends within its bound: report.max_distance <= report.max_bound.
  //! Under a CancelScope (core/parallel.h) a raised flag stops it within a chunk of work:
  //! Error(Cancelled), `refined` partly moved.
  PostPassReport apply(Mesh& refined, const PostPassParams& params) const;
  //! apply(), with snaps kept only when they turn no more faces over kFoldDegrees than the
  //! deviation bound alone does (they can still turn thin faces along some rims over);
  //! otherwise `refined` gets the bound alone and report.withdrawn_turned_faces says how
  //! many the snaps turned. Holds a copy of the positions while it decides.
  PostPassReport apply_guarded(Mesh& refined, const PostPassParams& params) const;

  //! Bytes the input surface holds from its construction to its destruction (its copy of the
  //! positions and triangles, per-face normals, bounds, regions and crease links, the AABB
  //! tree with its distance-query search tree), plus the transient peak of detect_regions
  //! when `regions` (run before it, on the same input): an upper bound, checked against the
  //! heap by tests/primitives (PrimitivesMemory).
  static std::uint64_t predict_bytes(std::uint64_t input_vertices, std::uint64_t input_faces,
                                     bool regions);
  //! Bytes apply() allocates for a refined mesh of `output_vertices` (one outcome per vertex,
  //! each worker's query buffers).
  static std::uint64_t predict_apply_bytes(std::uint64_t output_vertices);

  //! The default deviation bound of input face f (mm).
  double default_bound(std::size_t face) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace stlrefine::primitives
