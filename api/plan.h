// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// A request resolved once: its parameters parsed and validated, its scheme made (with its
// options), the shape of its STL body read by core/io's sniffer, and what it will make
// (faces, memory). The CLI, the daemon's routes and the job runner all start from a plan and
// carry it to run_refine; nothing downstream parses, validates or makes a scheme again.

#include <cstdint>
#include <memory>
#include <span>
#include <utility>

#include "api/memory_model.h"
#include "api/params.h"
#include "core/io/stl.h"
#include "core/schemes/scheme.h"

namespace stlrefine::api {

//! A refinement, resolved.
struct RefinePlan {
  RefineRequest request;  //!< parsed and validated
  //! Made once from request.refine (scheme name and options). Shared: a plan can be copied.
  std::shared_ptr<const Scheme> scheme;
  StlShape shape;  //!< of the body (empty in a plan made without it)
  //! Faces the refinement makes from shape.faces (predict_faces: exact in the uniform
  //! mode, a bound in the adaptive one).
  std::uint64_t predicted_faces = 0;
  MemoryEstimate memory;  //!< estimate_refine_memory for the plan's sink
};

//! Parses `raw` (parse_refine_fields), validates the parameters and makes the scheme
//! (make_scheme(RefineParams)), reads the body's shape and predicts the faces and memory.
//! Refuses nothing else: admission (the face budget, the memory budget) is the caller's.
//! \throw Error(InvalidParameter) naming the field, as parse_refine_params.
RefinePlan plan_refine(const RawParams& raw, const RequestLimits& limits,
                       std::span<const std::uint8_t> bytes, ResultSink sink = ResultSink::Answer);
//! The same for a request parsed earlier (a job stored it).
RefinePlan plan_refine(RefineRequest request, std::span<const std::uint8_t> bytes,
                       ResultSink sink = ResultSink::Answer);
//! The parameters and the scheme alone, before the body is read (the CLI: it reports a bad
//! parameter before it opens the file, and has no memory budget; the daemon: it refuses a bad
//! parameter before the upload): `shape`, `predicted_faces` and `memory` are left empty.
RefinePlan plan_refine(RefineRequest request);
//! Completes a plan made before the body (plan_refine(RefineRequest)) with the body's shape,
//! the predicted faces and memory: nothing is parsed, validated or made again.
RefinePlan plan_body(RefinePlan plan, std::span<const std::uint8_t> bytes,
                     ResultSink sink = ResultSink::Answer);

//! The plan's own face budget on the body's facets (before ingest; run_refine checks the
//! ingested count again). \throw FaceBudgetError (BudgetExceeded, field max_faces).
void refuse_over_face_budget(const RefinePlan& plan);

//! A slice of the input, resolved.
struct SlicePlan {
  SliceRequest request;  //!< parsed and validated
  StlShape shape;
  MemoryEstimate memory;
  //! Made by plan_slice. (No default: `run_slice(bytes, {})` means a default SliceRequest.)
  SlicePlan(SliceRequest r, const StlShape& s, MemoryEstimate m)
      : request(std::move(r)), shape(s), memory(std::move(m)) {}
};
//! \throw Error(InvalidParameter) naming the field, as parse_slice_params.
SlicePlan plan_slice(const RawParams& raw, const RequestLimits& limits,
                     std::span<const std::uint8_t> bytes);
//! The same for parameters parsed before the body (parse_slice_params).
SlicePlan plan_slice(SliceRequest request, std::span<const std::uint8_t> bytes);

//! An info report, resolved.
struct InfoPlan {
  InfoRequest request;  //!< parsed and validated
  StlShape shape;
  MemoryEstimate memory;
  //! Made by plan_info. (No default: `run_info(bytes, {})` means a default InfoRequest.)
  InfoPlan(InfoRequest r, const StlShape& s, MemoryEstimate m)
      : request(std::move(r)), shape(s), memory(std::move(m)) {}
};
//! \throw Error(InvalidParameter) naming the field, as parse_info_params.
InfoPlan plan_info(const RawParams& raw, std::span<const std::uint8_t> bytes);
//! The same for parameters parsed before the body (parse_info_params).
InfoPlan plan_info(InfoRequest request, std::span<const std::uint8_t> bytes);

}  // namespace stlrefine::api
