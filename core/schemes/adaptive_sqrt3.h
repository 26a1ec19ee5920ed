// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "core/schemes/sqrt3_host.h"

namespace stlrefine {

//! What must exist before a triangle of level l is refined.
enum class Sqrt3Closure : std::uint8_t {
  //! Every level-l triangle around its corners, so its whole stencil is in the mesh
  //! (Labsik-Greiner 3.2 and Kobbelt: "missing stencil vertices are produced recursively";
  //! spec 3.6 step 1). The default.
  Stencil,
  //! Only its three edge neighbours at level l: the least that keeps the output
  //! conforming with edge neighbours at most one level apart. The points are the same (the
  //! stencil is evaluated on the hierarchy either way); the mesh has fewer triangles.
  EdgeNeighbours,
};

//! When the adaptive sqrt3 mode refines a triangle. A criterion is on when it is > 0; a
//! triangle is refined when any criterion that is on asks for it.
struct Sqrt3AdaptiveCriteria {
  //! Degrees: the triangle's normal differs by more than this from the normal of a
  //! neighbour of the same level across a non-sharp edge (Labsik-Greiner section 6 use 20
  //! and 10).
  double angle_deg = 0;
  //! Model units (mm): the surface two levels finer lies farther than tol / 1.22 from the
  //! triangle somewhere over it (in its prism; across a sharp edge, beyond it too). 1.22 =
  //! 1 / (1 - 0.180) bounds what the later levels add: per double step the deviation
  //! shrinks at least by the double step's largest eigenvalue below 1/3 (0.180 at valence
  //! 6). Two levels, because one adds only the face point, which sees no curvature along
  //! the triangle's edges; after two every edge is trisected. The pieces of a refined
  //! triangle whose edges are not flipped yet are output faces too: where one is over (or
  //! the finer surface folds over it), the triangle across is refined. The promise, checked
  //! on irregular meshes: every output face within tol of the uniform level at the cap.
  double tol = 0;
  //! Triangles of this level are not refined, [1, 8].
  int max_level = 4;
  Sqrt3Closure closure = Sqrt3Closure::Stencil;
  //! AsStencil (production): an edge whose flip would fold is not flipped, and a face point
  //! whose fine faces fold moves towards its face's centroid, as in sqrt3_refine
  //! (adaptive_sqrt3_guard.cpp). Off: the stencil's rules alone, the same triangles and
  //! points as sqrt3_refine with FoldGuard::Off.
  FoldGuard guard = FoldGuard::AsStencil;
};

struct Sqrt3AdaptiveStats {
  std::size_t refined_by_criterion = 0;  //!< triangles a criterion asked to refine
  //! Triangles refined so that a refined triangle's stencil exists (spec 3.6 step 1) or to
  //! trisect a crease on both of its sides at once.
  std::size_t refined_by_closure = 0;
  int levels = 0;  //!< finest level of an output face
  //! Output faces at max_level that a criterion would still refine.
  std::size_t over_criterion_at_cap = 0;
  //! Of those, with the tolerance on: the largest distance (mm) of the surface two levels
  //! finer from such a face (what the criterion measures against tol / 1.22; finite ones
  //! only), and that face's centroid. 0 when none is over the tolerance.
  double max_over_tolerance = 0;
  Vec3 worst_over_tolerance_at{0, 0, 0};
  //! Edges of the hierarchy the fold guard left unflipped (in the output, or only measured
  //! by the criterion).
  std::size_t flips_kept = 0;
  //! Output face points the fold guard moved off the stencil's point.
  std::size_t face_points_pulled = 0;
};

//! Forward adaptive sqrt3 refinement (Labsik-Greiner section 3.2 after Kobbelt, spec 3.6)
//! for any Sqrt3Stencil.
//!
//! The triangles are those of the uniform sqrt3 hierarchy (levels M_0, M_1, ..., exactly
//! what sqrt3_refine makes), materialised on demand. Refining a triangle T of level l
//! splits it 1-to-3 (in a trisecting step, a triangle along a sharp edge is cut at the
//! trisection points instead, together with the triangle across the crease); an old edge
//! is flipped as soon as the triangles on both of its sides are refined. Only triangles
//! made by a flip (or kept whole along a sharp edge) can be refined again. Before T is
//! refined every level-l triangle around its corners is made to exist, by refining coarser
//! triangles recursively (spec 3.6 step 1): so the stencil of T's face point is in the
//! mesh, edge neighbours differ by at most one level, and the output is conforming (no
//! cracks, no T-junctions, no temporary triangles): watertight in, watertight out.
//!
//! Every point is the one the uniform hierarchy has at that level, computed by the
//! stencil's own face_point / curve_points / vertex_point on a small patch of the level.
//! Interpolating stencils keep every input vertex bit-identical; for approximating ones an
//! output vertex is at its position on the finest level among the faces around it.
//!
//! Memory: the criterion measures two levels below a triangle, so the hierarchy holds
//! several times more triangles than the output has faces, and how many depends on the
//! geometry. `reserve`, when set, is called with the bytes the object will hold at most
//! until its next call (its arrays, which grow a chunk of 16384 elements at a time, the
//! stencil patches alive at once, and the work array of the moment) before each chunk is
//! allocated and before result() builds the mesh; it throws to stop the refinement.
class AdaptiveSqrt3 {
 public:
  //! \pre coarse is an input level (step 0); the stencil outlives this object; `coarse`
  //! may go once this is made.
  AdaptiveSqrt3(const Level& coarse, const Sqrt3Stencil& stencil,
                const Sqrt3AdaptiveCriteria& criteria,
                std::function<void(std::uint64_t bytes)> reserve = {});
  ~AdaptiveSqrt3();
  AdaptiveSqrt3(const AdaptiveSqrt3&) = delete;
  AdaptiveSqrt3& operator=(const AdaptiveSqrt3&) = delete;

  //! Refines until no triangle below max_level asks for it. Calls level_started(l) when the
  //! first triangle of level l is examined.
  //! \throw Error(BudgetExceeded, field "max_faces") before the output would pass max_faces;
  //! Error(Cancelled) when cancel, or the flag of the CancelScope this is called in, is
  //! raised: checked before every triangle is examined and before every split.
  void run(std::uint64_t max_faces, const std::atomic<bool>* cancel = nullptr,
           const std::function<void(int)>& level_started = {});

  //! The conforming mesh: input vertex v is output vertex v, new vertices follow. With
  //! face_level, the level of every output face (a face split 1-to-3 whose old edge is
  //! not flipped yet counts as its parent's level + 1).
  Level result(std::vector<std::uint8_t>* face_level = nullptr);

  const Sqrt3AdaptiveStats& stats() const;

 private:
  class Hierarchy;
  std::unique_ptr<Hierarchy> h_;
};

}  // namespace stlrefine
