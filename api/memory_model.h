// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// The memory model: the peak memory a request will need, predicted from the STL bytes and
// the parameters before any work, so the daemon can refuse (422) or delay (503) a request
// instead of running out of memory in the middle of it. Calibrated against the peak RSS
// the real daemon adds per request (bench/reliability/memory_calibration.cpp); the
// coefficients, the calibration set and the error are in memory_model.cpp.
//
// Uniform refinement: the prediction is the peak (an upper bound on the calibration set).
// Adaptive refinement: how far it refines depends on the geometry, and the only bound known
// before the work, the uniform count at max_level, is up to 137 times what adaptive runs
// use (and an adaptive sqrt3 hierarchy holds several triangles per output face besides).
// So the prediction is an admission figure: what the first level needs. The growth past it
// is enforced while it happens: api::run_refine's MemoryGrowFn receives whole-request
// figures, true upper bounds of what the refinement is about to hold, and the request stops
// (MemoryBudgetError, core/refine.h) the moment one does not fit. A caller that admits an
// adaptive request on this figure must pass that callback.

#include <cstdint>
#include <span>
#include <string>

#include "api/params.h"
#include "api/problem.h"
#include "core/io/stl.h"
#include "core/refine.h"

namespace stlrefine::api {

//! The shape of an STL body, from core/io's sniffer.
using stlrefine::stl_shape;
using stlrefine::StlShape;

//! Facet-plane crossings of the plan `params` would make on the facets in `bytes`: one pass
//! over the corners' z values, planes as slicer::plan_layers places them (uniform from the
//! part's bounds, or explicit heights). What the slicer's exact pre-pass would count on the
//! ingested mesh, up to welding and repair. 0 when the bytes are no STL.
std::uint64_t count_crossings(std::span<const std::uint8_t> bytes, const StlShape& shape,
                              const slicer::SliceParams& params);

//! A prediction.
struct MemoryEstimate {
  //! Peak memory the request adds to an idle daemon, its body included, in bytes.
  //! In the adaptive mode an admission figure for the first level (see above).
  std::uint64_t peak_bytes = 0;
  //! Refinement output; in the adaptive mode a bound (the uniform count at max_level, at
  //! most max_faces), for disk space, not memory.
  std::uint64_t output_faces = 0;
  //! Estimated slice output points (0 without slicing); in the adaptive mode at the
  //! output_faces bound, like it.
  std::uint64_t contour_points = 0;
  //! Bytes of the answer the daemon keeps until it is sent (the STL, contours or zip).
  std::uint64_t answer_bytes = 0;
  //! The parameter to lower when the prediction is over a budget: "levels", "max_level",
  //! "slice", "layer_height", "heights"; empty when only a smaller input would help.
  std::string field;
};

//! Where the result goes: the answer of a synchronous request (refine + slice is then a zip
//! built in memory) or a job's files on disk.
enum class ResultSink { Answer, JobFiles };

//! A refinement (optionally sliced) with `scheme`, the one made from request.refine.
//! `bytes` is the body (for the slice estimate).
MemoryEstimate estimate_refine_memory(std::span<const std::uint8_t> bytes, const StlShape& shape,
                                      const RefineRequest& request, const Scheme& scheme,
                                      ResultSink sink = ResultSink::Answer);
//! The same with the scheme request.refine names (made here).
MemoryEstimate estimate_refine_memory(std::span<const std::uint8_t> bytes, const StlShape& shape,
                                      const RefineRequest& request,
                                      ResultSink sink = ResultSink::Answer);
//! api::run_refine's figure once the refinement is done: the body, the refined mesh's
//! arrays (`mesh_bytes`, see stlrefine::mesh_bytes), the STL it is written to and, with a
//! slice, what slicing adds, predicted as estimate_refine_memory does but from the faces
//! actually made. `shape`: the body's (stl_shape, as the plan has it); `input_faces`: of the
//! ingested mesh.
std::uint64_t refined_memory_bytes(std::span<const std::uint8_t> bytes, const StlShape& shape,
                                   const RefineRequest& request, std::uint64_t input_faces,
                                   std::uint64_t output_faces, std::uint64_t mesh_bytes);

//! Bytes write_stl allocates for `faces` facets at most (ASCII: the longest facet text).
std::uint64_t stl_bytes(std::uint64_t faces, StlFormat format);

//! The 422 of a refinement stopped by its MemoryGrowFn with a figure above `capacity`
//! (never fits): as memory_budget_problem, predicted_bytes the figure refused.
Problem memory_budget_problem(const MemoryBudgetError& error, std::uint64_t capacity);

//! A slice of the input as it is.
MemoryEstimate estimate_slice_memory(std::span<const std::uint8_t> bytes, const StlShape& shape,
                                     const SliceRequest& request);
//! An info report.
MemoryEstimate estimate_info_memory(const StlShape& shape,
                                    repair::RepairMode repair = repair::RepairMode::None);

//! The 422 of a request whose prediction is over what one request may reserve
//! (`capacity`): type budget-exceeded, title "Memory budget exceeded", reason
//! "memory_budget", `field` from the estimate, and `predicted_bytes`, `memory_budget_bytes`.
Problem memory_budget_problem(const MemoryEstimate& estimate, std::uint64_t capacity);

}  // namespace stlrefine::api
