// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "core/error.h"
#include "core/features/features.h"
#include "core/mesh/array_pool.h"
#include "core/mesh/mesh.h"
#include "core/progress.h"
#include "core/schemes/registry.h"
#include "core/schemes/scheme.h"

namespace stlrefine {

//! What a refinement request asks for. Every field has its range next to it.
struct RefineParams {
  std::string scheme = "butterfly";  //!< one of scheme_names()
  int levels = 1;                    //!< [0, 8]
  FeatureParams features;
  std::uint64_t max_faces = 20'000'000;  //!< [1, 2^31): refuse before work above this
  int threads = 0;                       //!< [0, 256]; 0 = every core
  //! Curvature-adaptive mode when this or adaptive_angle is > 0 (`levels` is then unused):
  //! chordal tolerance in model units (mm) [0, 1e6]. 1-to-4 schemes (interpolating ones:
  //! lsf, butterfly) split edges whose edge point leaves the chord by more than this,
  //! red-green closed; sqrt3 schemes refine triangles whose new point leaves the flat
  //! triangle (a trisection point its chord) by more, forward adaptive (spec 3.6).
  double adaptive_tol = 0;
  //! Curvature-adaptive criterion in degrees [0, 180]: refine where the normals of two
  //! neighbouring faces across a non-sharp edge differ by more than this (Labsik-Greiner
  //! use 20 and 10). With adaptive_tol as well, either criterion refines.
  double adaptive_angle = 0;
  int max_level = 4;  //!< [1, 8]: the level cap of the adaptive mode
  //! The options of schemes (sqrt3-unified's alpha and alpha_features, loop-g2's kappa
  //! and ramp_steps, ...), by name: those given; a scheme reads its own and ignores the
  //! others, missing ones at their defaults. Declared with their ranges in the registry
  //! (core/schemes/registry.cpp).
  SchemeOptions scheme_options;

  //! True when a curvature-adaptive criterion is on.
  bool adaptive() const { return adaptive_tol > 0 || adaptive_angle > 0; }

  //! \throw Error(InvalidParameter) naming the field. Makes the scheme (default options)
  //! when an adaptive mode is asked for; make_scheme(params) validates and makes it once.
  void validate() const;
  //! validate() for `scheme`, the one made from these params: the ranges and whether
  //! `scheme` has the adaptive mode asked for; makes nothing.
  void validate(const Scheme& scheme) const;
};

//! The scheme params name, with their options, after validating them: a request makes its
//! scheme once, here, and hands it to check_face_budget and refine.
//! \throw Error(InvalidParameter) naming the field, as RefineParams::validate.
std::unique_ptr<Scheme> make_scheme(const RefineParams& params);

class Split4Stencil;
//! The 1-to-4 stencil the adaptive mode uses with `scheme`, or null when it has none (the
//! red-green mode needs an interpolating 1-to-4 scheme).
const Split4Stencil* adaptive_scheme(const Scheme& scheme);
class Sqrt3Stencil;
//! The stencil of a sqrt3 scheme (every one has the forward adaptive mode), or null.
const Sqrt3Stencil* adaptive_sqrt3_scheme(const Scheme& scheme);

//! Memory admission while a refinement grows. Called with the peak bytes the refinement
//! will hold from now on (its arrays as they are about to grow, a true upper bound for the
//! next step, until the next call); returns false when that does not fit. The figures
//! only rise: a call is made when the next step needs more than was granted so far.
//! The adaptive hosts call it before every growth of their hierarchy (the sqrt3 one a chunk
//! of at most 0.9 MiB at a time, the 1-to-4 one per phase of a step) and before they build
//! their output; uniform refinement once per level.
//!
//! What a figure counts: every array the refinement allocates (rounded as the allocators
//! round them), the input mesh it was given and its features, plus kRefineSlackBytes for
//! small buffers (stencil patches, per-thread scratch, allocator headers). Not counted:
//! the array pool's slabs (core/mesh/array_pool.h, at most 64 MiB per process, which the
//! daemon keeps in its own reserve) and what the caller holds (api::run_refine adds the
//! request body and the STL it writes).
using MemoryGrowFn = std::function<bool(std::uint64_t bytes)>;

//! What a figure adds for small buffers besides the counted arrays.
inline constexpr std::uint64_t kRefineSlackBytes = std::uint64_t{8} << 20;

//! Thrown by refine (and api::run_refine) when a MemoryGrowFn returned false: code
//! BudgetExceeded, reason "memory_budget", field "max_level" (adaptive) or "levels"
//! (uniform), the message naming the bytes and the level.
//!
//! "Does not fit now" or "never fits": the error cannot know the caller's capacity, so the
//! caller compares needed_bytes() (the figure its callback refused) with what one request
//! may ever hold: above it the request can never run (422 with the field; lower max_level /
//! levels), at or below it it did not fit next to the other requests (503, retry later).
class MemoryBudgetError : public Error {
 public:
  MemoryBudgetError(std::string field, int level, std::uint64_t needed_bytes);
  //! The figure the callback refused.
  std::uint64_t needed_bytes() const { return needed_bytes_; }
  //! The level being made when it was refused (adaptive: the finest level in the making).
  int level() const { return level_; }

 private:
  int level_;
  std::uint64_t needed_bytes_;
};

struct RefineReport {
  std::string scheme;
  int levels = 0;
  std::size_t input_vertices = 0, input_faces = 0;
  std::size_t output_vertices = 0, output_faces = 0;
  std::size_t sharp_edges_in = 0, sharp_edges_out = 0;
  std::size_t corners = 0, creases = 0, darts = 0;
  std::size_t fold_fallbacks = 0;
  //! Adaptive mode: the criteria, steps made (`levels`: the finest level reached) and, at
  //! the cap, the edges (1-to-4) or faces (sqrt3) a criterion would still refine.
  double adaptive_tol = 0;
  double adaptive_angle = 0;
  std::size_t edges_over_tolerance = 0;
  std::size_t faces_over_criterion = 0;
  //! Adaptive mode: why the refinement stopped. "tolerance": nothing is over a criterion
  //! any more (the tolerance is reached everywhere); "max_level": the level cap was reached
  //! with edges_over_tolerance edges (1-to-4) or faces_over_criterion faces (sqrt3) still
  //! over a criterion. Empty in the uniform mode. (Past max_faces or the memory budget the
  //! refinement throws instead, naming the field.)
  std::string stop_reason;
  //! 1-to-4 adaptive mode stopped at the cap: the largest distance (mm) of a remaining
  //! edge's point from its chord midpoint (what adaptive_tol bounds), and where: that
  //! edge's chord midpoint. 0 when nothing is over the tolerance.
  double max_over_tolerance = 0;
  Vec3 worst_over_tolerance_at{0, 0, 0};
  //! ... and of edges_over_tolerance, the halves of a split edge whose point leaves the
  //! chord by more than half as far as the split edge's midpoint did: there the scheme's
  //! own levels are not converging (about four times less per level where they do), so a
  //! higher max_level would not reach the tolerance there either.
  std::size_t edges_not_converging = 0;
  //! Largest distance any input vertex moved (0 for interpolating schemes).
  double max_input_displacement = 0;
  double seconds = 0;
};

struct RefineResult {
  Mesh mesh;
  RefineReport report;
  //! The output's sharp edges and vertex kinds, as the hosts carried them from the input
  //! (a new vertex on a sharp edge is a crease vertex): what tells the post-pass
  //! (primitives/) which new vertices lie on a crease.
  Features features;
};

//! Predicted face count; \throw Error(BudgetExceeded, field "max_faces") with the
//! number in the message when it exceeds params.max_faces. In the adaptive mode it is an
//! upper bound (the uniform count at max_level) and is not enforced here: the refinement
//! stops with the same error as soon as its exact count would pass max_faces.
std::uint64_t check_face_budget(std::size_t faces, const Scheme& scheme,
                                const RefineParams& params);
//! check_face_budget with the scheme params name (made here).
std::uint64_t check_face_budget(std::size_t faces, const RefineParams& params);

//! Faces the refinement makes from `faces` faces: exact in the uniform mode; in the adaptive
//! mode a bound, the uniform count at max_level capped at max_faces (where it stops).
std::uint64_t predict_faces(std::uint64_t faces, const Scheme& scheme, const RefineParams& params);

//! What the adaptive sqrt3 host needs: no two edges join the same two vertices and no two
//! faces have the same three. Its output's edges are known by their vertex pairs; ingest
//! leaves doubled edges where it cuts a non-manifold edge apart, and a facet plus its
//! reverse is a two-face pillow. Uniform levels and the adaptive 1-to-4 host (lsf,
//! butterfly) refine such meshes.
//! \throw Error(NotTriangleMesh, "adaptive_non_simple") naming the vertices or faces.
void require_simple_mesh(const Mesh& mesh);

//! Called in the uniform mode after each level but the last (`level` = 1 after the first),
//! before the next level is made from it: may move the level's vertices (the request
//! pipeline puts new vertices of recognised primitives onto them, so the next level's
//! stencils work on the true surface). The level's carried state (smooth normals, sqrt3
//! parity, alpha) stays as the scheme made it. Runs inside refine's thread arena.
using BetweenLevelsFn = std::function<void(Mesh& mesh, const Features& features, int level)>;

//! Applies `scheme` (made from params: make_scheme(params)) params.levels times. Checks the
//! parameters' ranges for `scheme` (RefineParams::validate(const Scheme&), nothing is made)
//! and the face budget before any work, the cancel flag between levels, and asks `grow`
//! (when set) before the memory it holds grows (see MemoryGrowFn). Takes the mesh by value:
//! move it in to save a copy. `features`: detect_features(mesh, params.features) when the
//! caller has it already (it is detected here otherwise). `between_levels`: see
//! BetweenLevelsFn.
//! \throw Error(InvalidParameter | BudgetExceeded | Cancelled); MemoryBudgetError when grow
//! said no; Error(NotTriangleMesh) in the adaptive mode of a sqrt3 scheme on a mesh that is
//! not simple (see require_simple_mesh).
RefineResult refine(Mesh mesh, const Scheme& scheme, const RefineParams& params,
                    const ProgressFn& progress = {}, const std::atomic<bool>* cancel = nullptr,
                    const MemoryGrowFn& grow = {}, std::optional<Features> features = {},
                    const BetweenLevelsFn& between_levels = {});
//! refine with the scheme params name: make_scheme(params), then the above.
RefineResult refine(Mesh mesh, const RefineParams& params, const ProgressFn& progress = {},
                    const std::atomic<bool>* cancel = nullptr, const MemoryGrowFn& grow = {});

//! Bytes the allocator takes for n elements of T in a BigVector (HugePageAllocator): whole
//! 2 MiB pages from 2 MiB up, the array pool's size class from 4 KiB, else the bytes.
template <class T>
std::uint64_t big_vector_bytes(std::size_t n) {
  const std::uint64_t bytes = std::uint64_t(n) * sizeof(T);
  constexpr std::uint64_t kHuge = std::uint64_t{2} << 20;
  if (bytes >= kHuge) return (bytes + kHuge - 1) / kHuge * kHuge;
  const std::size_t pooled = array_pool::block_bytes(static_cast<std::size_t>(bytes));
  return pooled ? pooled : bytes;
}

//! Bytes the arrays of a mesh hold (their capacities, rounded as big_vector_bytes).
std::uint64_t mesh_bytes(const Mesh& mesh);
//! ... and of a level: its mesh, features, alpha and irregular-vertex list.
std::uint64_t level_bytes(const Level& level);

}  // namespace stlrefine
