// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <array>
#include <cstdint>
#include <span>

#include "core/schemes/host_scheme.h"
#include "core/schemes/scheme.h"

namespace stlrefine {

//! One sqrt3 step as a stencil sees it: the coarse level, whether this step trisects the
//! sharp edges (every second step, spec 3.1), and the per-vertex alpha when the stencil
//! blends per vertex (empty otherwise).
struct Sqrt3Step {
  const Mesh& mesh;
  const Features& features;
  //! True in steps 2, 4, 6, ...: sharp edges are trisected and the faces along them get
  //! no face point.
  bool trisects = false;
  //! Per coarse vertex; empty unless the stencil asked for it (Sqrt3Stencil::initial_alpha).
  std::span<const double> alpha;
  //! In trisecting steps, per coarse face: the corner k whose half-edge 3f+k is the face's
  //! one sharp edge, or 3 for none. Empty in the other steps. Stencils read it too: such a
  //! face is a piece the previous step kept whole, two triangles of this level's lattice.
  std::span<const std::uint8_t> sharp_corner;

  //! False for the faces along a sharp edge in a trisecting step (they are split by
  //! joining their apex to the two trisection points instead).
  bool has_face_point(FaceId f) const { return !trisects || sharp_corner[f.idx] == 3; }
};

//! Where a stencil writes its points: one per coarse vertex (the old vertex's new
//! position) and one per coarse face (its face point; entries of faces without a face
//! point are not read).
struct Sqrt3Points {
  std::span<Vec3> vertices;
  std::span<Vec3> faces;
};

//! The geometric rules of a sqrt3-family scheme (the stencil): face points, old-vertex
//! points and the trisection points of sharp edges. Reads the coarse level only.
class Sqrt3Stencil {
 public:
  virtual ~Sqrt3Stencil() = default;
  //! True when old vertices never move (their points are exact copies).
  virtual bool interpolating() const = 0;
  //! Whether the host runs its fold guard after this stencil (all built-in stencils; a
  //! test stencil that must see its linear rules alone says no).
  virtual bool guards_folds() const { return true; }
  //! Per-vertex alpha of an input level (one without Level::alpha) for stencils that blend
  //! per vertex; empty for the others. The host carries it to new vertices (LL eq. 7).
  virtual BigVector<double> initial_alpha(const Level&) const { return {}; }
  //! Writes out.vertices[v] for every coarse vertex and out.faces[f] for every face with
  //! step.has_face_point(f).
  virtual void points(const Sqrt3Step& step, Sqrt3Points out) const = 0;
  //! What points() writes for face f (step.has_face_point(f)) and for old vertex v, one at
  //! a time: the adaptive host evaluates the stencil on small patches of a level.
  virtual Vec3 face_point(const Sqrt3Step& step, FaceId f) const = 0;
  virtual Vec3 vertex_point(const Sqrt3Step& step, VertexId v) const = 0;
  //! Trisecting steps only: the new points at 1/3 and 2/3 of sharp half-edge h, counted
  //! from from(h). Uses curve vertices only, so both sides of a crease agree.
  virtual std::array<Vec3, 2> curve_points(const Sqrt3Step& step, HalfedgeId h) const = 0;
};

//! One sqrt3 step (spec 3.1). Odd steps (coarse.step even): a face point in every face,
//! 1-to-3 split, every non-sharp old edge flipped unless the fold guard keeps it. Even
//! steps: sharp edges trisected, the faces along them split by joining their apex to the
//! trisection points, face points in the others, every non-sharp old edge flipped unless the
//! fold guard keeps it. F x3 per step in every case (a kept edge leaves the two 1-to-3
//! children beside it instead of the two flipped ones), sharp edges x3 per even step; no
//! old edge that is sharp is ever flipped.
//!
//! Layout of the fine level (derived arithmetically, no maps):
//! - vertices: old ids kept; V + f is the face point of coarse face f or, when f has no
//!   face point, the trisection point of its sharp edge nearest the edge's start; the
//!   second trisection point of a boundary edge gets V + F + (rank among boundary edges).
//! - faces: fine face h belongs to coarse half-edge h: the flipped triangle
//!   (from(h), apex across, apex of h), or for a sharp or kept h the triangle it keeps.
//! Fold guard (issue 17 item 2, when stencil.guards_folds()), against the smooth normals
//! of the input (its sector_normals, split4_host.h, carried from step to step in
//! Level::smooth_normals: the fine level gets them when coarse.pass_smooth_normals) with the
//! limit kSqrt3FoldAngleDeg:
//! - topological: a non-sharp edge whose flip would fold (a flipped child past the limit,
//!   or the quad (a, q_g, b, q_f) not convex seen along the edge's smooth normal) is not
//!   flipped; the face points of its two faces join both of its ends. Decided with the
//!   stencil's points, and again after the face points moved (then the face points beside a
//!   newly kept edge go back to the stencil's), a few rounds;
//! - geometric: where a fine face still folds, its face points move towards their face's
//!   centroid (then towards its largest-angle corner); a child of a cut face with no face
//!   point has its sharp edge's two trisection points moved towards the chord's thirds.
//! - a degenerate fine face counts as folded (both halves): lower than a few float ulps of
//!   its coordinates (the binary STL's rounding could turn it over), or thinner than a tenth
//!   of the coarse faces it comes from (a near-flat flip), unless those are that thin already.
//! Before the plane rule and the fold guard, for interpolating stencils, the normal check
//! (issue 17 item 3, ours): the face point of a face with a corner of uneven spokes (ratio 2
//! and up, unless its ring is a lifted lattice) becomes the PN-triangle centroid of the
//! corners' smooth normals (core/geometry/pn_centroid.h) when it strays from it along their
//! mean normal (split4's NormalCheckParams slack and height fraction); interpolating stencils
//! take lsf's relaxed guard normals as the input's smooth normals (for the check and the guard).
//! Old vertices never move (interpolating stencils stay interpolating); trisection points
//! stay on their sharp edge's curve rule or move towards its chord, both sides alike.
//! Counted in stats.fold_fallbacks (face points and trisection pairs moved, edges kept).
//! \throw Error(Internal) when a trisecting step meets a face with two sharp edges (a
//! level not made by this host with the step parity it claims).
//! `guard` Off: the stencil's rules alone (the spectral analysis).
Level sqrt3_refine(const Level& coarse, const Sqrt3Stencil& stencil, StepStats& stats,
                   FoldGuard guard = FoldGuard::AsStencil);

//! The sqrt3 fold guard's limit (degrees) against the smooth normals, tighter than split4's
//! kFoldAngleDeg (60): chosen when each level's smooth normals were the sector normals of the
//! level before, which drift from the true surface's (by 30-37 degrees after 3 steps next to
//! the rounded box's fanned corners), so a guard at 60 let faces 60-80 degrees off the truth
//! through. The normals are carried from the input now (bench/results-issue17-s5-folds.md);
//! the adaptive host still estimates them per level. Tuned on seeds 1000-1003 of the CAD-like
//! families: 30 against 60 gives far fewer faces past 60 degrees from the truth and the same or a
//! lower RMS (bench/results-issue17-sqrt3.md). 20 was better still, but then the guard changes the
//! spectral analysis's probe steps, had it refined with the guard (it runs sqrt3_refine with
//! FoldGuard::Off, as split4).
inline constexpr double kSqrt3FoldAngleDeg = 30.0;

//! Heap bytes sqrt3_refine(coarse, ...) allocates at most, the fine level included, for the
//! built-in stencils (their scratch: at most 32 B per coarse vertex).
std::uint64_t sqrt3_step_bytes(const Level& coarse);

//! The sqrt3 host of HostScheme<Sqrt3Stencil> (host_scheme.h).
template <>
struct Host<Sqrt3Stencil> {
  static constexpr unsigned kFacesPerFace = 3;
  static Level step(const Level& coarse, const Sqrt3Stencil& stencil, StepStats& stats) {
    return sqrt3_refine(coarse, stencil, stats);
  }
};

}  // namespace stlrefine
