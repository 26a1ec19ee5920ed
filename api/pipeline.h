// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <atomic>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <span>
#include <string>

#include "api/params.h"
#include "api/plan.h"
#include "core/refine.h"

namespace stlrefine::api {

//! `info`: bytes -> read_stl -> weld -> build_mesh -> compute_stats + detect_features +
//! LSF curvatures. Returns the report (see info_report; `curvature` is the summary).
//! \throw Error(MalformedStl | NotTriangleMesh | InvalidParameter)
nlohmann::ordered_json run_info(std::span<const std::uint8_t> bytes, const InfoRequest& request);

struct InfoOutcome {
  nlohmann::ordered_json report;  //!< as run_info
  //! Per vertex of the ingested (welded) mesh, when asked for:
  //! `vertex,x,y,z,kind,gaussian,mean,k1,k2,valid` (header line first).
  std::optional<std::string> curvature_csv;
};

//! run_info of a plan (the daemon's: its request parsed and validated before the body).
nlohmann::ordered_json run_info(std::span<const std::uint8_t> bytes, const InfoPlan& plan);

//! run_info, optionally with the per-vertex curvature table.
InfoOutcome run_info(std::span<const std::uint8_t> bytes, const InfoRequest& request,
                     bool curvature_csv);

//! The face budget of run_refine (RefineParams::max_faces against the predicted output),
//! for callers that know the face count before ingest (the daemon, from the STL's size).
//! \throw FaceBudgetError (BudgetExceeded, field max_faces) with the predicted face count.
void refuse_over_face_budget(std::uint64_t faces, const Scheme& scheme, const RefineParams& params);

struct RefineOutcome {
  std::string stl;                //!< the refined mesh as STL bytes (request.output_format)
  nlohmann::ordered_json report;  //!< see refine_report; with a slice, also `slice`
  //! The refined mesh's contours in request.slice->format, when request.slice is set.
  std::optional<std::string> contours;
};

//! `refine`, the one path both the CLI and the daemon take:
//! bytes -> read_stl -> weld -> build_mesh -> face budget -> refine -> write_stl.
//! The face budget is checked right after ingest, before any refinement work.
//! \throw Error(MalformedStl | NotTriangleMesh | InvalidParameter | Cancelled | Internal);
//! FaceBudgetError (an Error with code BudgetExceeded) with the predicted face count.
//! With request.slice, the slice plan is checked on the input's bounds before refining
//! (too many layers: BudgetExceeded, field max_layers), then the refined mesh is sliced.
//!
//! Memory: `grow` (see MemoryGrowFn in core/refine.h), when set, receives whole-request
//! figures comparable with estimate_refine_memory's peak_bytes: the body (`bytes`) plus,
//! while refining, what refine holds (the input mesh, the hierarchy or levels, its slack),
//! then, before the STL is written, refined_memory_bytes (the refined mesh, the STL, and the
//! slice's contours predicted from the faces made, on the plan's shape of the body: with
//! `grow`, the plan is one made with the body). With the post-pass (primitives=auto or
//! max_deviation), first the body, the input mesh and InputSurface::predict_bytes before it
//! is built, that surface held beside refine's figures, and before it is applied the refined
//! mesh and predict_apply_bytes (refused: MemoryBudgetError, field "primitives", level 0 before
//! refining, the levels made after). Ingest is not metered: the up-front
//! estimate covers it. When grow says no: MemoryBudgetError (BudgetExceeded, reason
//! "memory_budget", field "max_level" or "levels") whose needed_bytes() is the refused
//! whole-request figure; compare it with what one request may hold to tell 422 from 503.
RefineOutcome run_refine(std::span<const std::uint8_t> bytes, const RefinePlan& plan,
                         const ProgressFn& progress = {}, const std::atomic<bool>* cancel = nullptr,
                         const MemoryGrowFn& grow = {});
//! run_refine for a request with `scheme` made from request.refine (make_scheme), for
//! callers without a plan.
RefineOutcome run_refine(std::span<const std::uint8_t> bytes, const RefineRequest& request,
                         const Scheme& scheme, const ProgressFn& progress = {},
                         const std::atomic<bool>* cancel = nullptr, const MemoryGrowFn& grow = {});
//! run_refine making the scheme request.refine names (validated first: a bad parameter is
//! reported before the body is read).
RefineOutcome run_refine(std::span<const std::uint8_t> bytes, const RefineRequest& request,
                         const ProgressFn& progress = {}, const std::atomic<bool>* cancel = nullptr,
                         const MemoryGrowFn& grow = {});

//! run_refine without making a binary STL in memory: the refined mesh instead, for callers
//! that stream its bytes (write_binary_stl, BinaryStl in core/io/stl.h) to a file or a
//! socket. Binary output: `outcome.stl` is empty and `mesh` is the refined mesh; the report
//! is run_refine's, with output.bytes the STL's size (84 + 50 n) and seconds.write 0 (the
//! bytes are made later: the CLI and the job runner, which write the report after the STL,
//! put their streamed write's time there and in seconds.total). ASCII output is written as
//! run_refine does (its size is known only once written): `outcome.stl` holds it and `mesh` is
//! empty.
struct RefinedMesh {
  RefineOutcome outcome;
  Mesh mesh;
  bool stream() const { return outcome.stl.empty(); }
};
RefinedMesh run_refine_to_mesh(std::span<const std::uint8_t> bytes, const RefinePlan& plan,
                               const ProgressFn& progress = {},
                               const std::atomic<bool>* cancel = nullptr,
                               const MemoryGrowFn& grow = {});
//! ... making the scheme request.refine names, for callers without a plan.
RefinedMesh run_refine_to_mesh(std::span<const std::uint8_t> bytes, const RefineRequest& request,
                               const ProgressFn& progress = {},
                               const std::atomic<bool>* cancel = nullptr,
                               const MemoryGrowFn& grow = {});

struct SliceOutcome {
  std::string contours;           //!< in request.slice.format
  nlohmann::ordered_json report;  //!< see slice_report
};

//! `slice`: bytes -> read_stl -> weld -> build_mesh -> plan (layer budget) -> contours.
//! \throw Error(MalformedStl | NotTriangleMesh | InvalidParameter | BudgetExceeded |
//! Cancelled | Internal)
SliceOutcome run_slice(std::span<const std::uint8_t> bytes, const SliceRequest& request,
                       const ProgressFn& progress = {}, const std::atomic<bool>* cancel = nullptr);
//! run_slice of a plan (the daemon's: its request parsed before the body).
SliceOutcome run_slice(std::span<const std::uint8_t> bytes, const SlicePlan& plan,
                       const ProgressFn& progress = {}, const std::atomic<bool>* cancel = nullptr);

//! Contours of `mesh` as one string in options.format (what run_slice and run_refine use).
std::string slice_to_string(const Mesh& mesh, const SliceOptions& options,
                            slicer::SliceStats* stats = nullptr, const ProgressFn& progress = {},
                            const std::atomic<bool>* cancel = nullptr);

}  // namespace stlrefine::api
