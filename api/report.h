// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <nlohmann/json.hpp>
#include <span>
#include <string>

#include "api/ingest.h"
#include "api/params.h"
#include "core/features/features.h"
#include "core/mesh/build_mesh.h"
#include "core/mesh/mesh_stats.h"
#include "core/refine.h"
#include "core/schemes/lsf_curvature.h"
#include "primitives/post_pass.h"
#include "primitives/regions.h"
#include "slicer/slice.h"

namespace stlrefine::api {

//! Every IngestReport counter, by its field name.
nlohmann::ordered_json ingest_report_json(const IngestReport& report);

//! The `info` report:
//! - `input`: format, triangles, trailing_bytes, vertices_before_weld (3 per facet),
//!   vertices_after_weld, weld_tolerance;
//! - `ingest`: ingest_report_json;
//! - `mesh`: vertices, edges, faces, boundary_edges, boundary_loops, components,
//!   zero_area_faces, euler_characteristic, watertight, genus (null unless watertight),
//!   bbox {min, max}, area, volume;
//! - `features`: crease_angle_deg, sharp_edges, corners, creases, darts.
nlohmann::ordered_json info_report(const Ingested& in, const MeshStats& stats,
                                   const Features& features, const InfoRequest& request);

//! The `curvature` member of the info report: valid and invalid vertex counts, then
//! {min, p05, p50, p95, max} of gaussian (1/mm^2), mean, k1, k2 and abs_max (1/mm), from the
//! LSF quadric fits (corners and degenerate fits are invalid). Nulls when no vertex is valid.
nlohmann::ordered_json curvature_summary_json(const CurvatureSummary& summary);

//! `vertex,x,y,z,kind,gaussian,mean,k1,k2,valid`, one line per vertex of `mesh` (after
//! welding), numbers as shortest round-trip doubles, kind smooth/dart/crease/corner,
//! valid 0/1.
std::string curvature_table_csv(const Mesh& mesh, const Features& features,
                                std::span<const VertexCurvature> curvatures);

//! Wall times of the refine request's phases, in seconds.
struct RefineTimes {
  double ingest = 0, refine = 0, write = 0, total = 0;
};

//! The `refine` report: scheme, levels, crease_angle_deg, `input` (as in info plus the
//! mesh's vertices and faces), `output` {format, vertices, faces, bytes}, `features`
//! {sharp_edges_in, sharp_edges_out (sharp edges kept), corners, creases, darts},
//! fold_fallbacks, adaptive_tol, adaptive_angle, edges_over_tolerance (1-to-4 adaptive) and
//! faces_over_criterion (sqrt3 adaptive) left at the level cap, max_input_displacement,
//! `seconds` {ingest, refine, write, total}, and `ingest`. Compact enough for a response header.
nlohmann::ordered_json refine_report(const Ingested& in, const RefineReport& report,
                                     const RefineRequest& request, std::size_t output_bytes,
                                     const RefineTimes& times);

//! The `primitives` member of the refine report: mode (auto/off), tolerance (fraction of
//! the bbox diagonal) and tolerance_mm, regions_found, faces_in_regions, and `regions`: the
//! largest 10 (by faces; the report is a response header), each {type, the primitive's parameters
//! (point, axis, radius, minor_radius, half_angle_deg as the type has them), faces, vertices,
//! max_residual (mm), grown}; then snapped, snapped_to_curve, snap_refused, snaps_reverted (a snap
//! that turned a face over, taken back), max_snap_move (mm). Only mode and tolerance when regions
//! is null (primitives=off; or `skipped` with the reason: an approximating scheme without
//! max_deviation, whose moved input vertices the default post-pass would undo).
nlohmann::ordered_json primitives_report_json(const primitives::RegionMap* regions,
                                              const primitives::PostPassReport& post,
                                              const PrimitiveOptions& options);

//! The `deviation` member: what a bureau can check without the true surface. bound ("auto"
//! or the mm value; "off"), max_bound (mm), checked_vertices (output vertices that are not
//! input vertices), max_distance_from_input (of any output vertex from the input surface,
//! after the pass, mm), max_distance_before (before it), pulled_back (vertices moved back
//! within the bound), max_pull_back (mm), worst_normal_change_deg (largest angle between an
//! output face and the input faces near it that agree best, see
//! primitives::PostPassReport),
//! faces_turned_over_60_deg, detect_seconds (region detection and the input surface), seconds (the
//! pass itself). The guard's folded faces are the report's `fold_fallbacks`. With an approximating
//! scheme and no max_deviation the pass only measures (bound "off", nothing moved).
nlohmann::ordered_json deviation_report_json(const primitives::PostPassReport& post,
                                             const PrimitiveOptions& options);

//! The slice part of a report: format, layer_height (null for explicit heights), z_min,
//! z_max (null when not given), layers, outer_loops, holes, open_polylines, points,
//! degenerate_loops, reversed_loops, bytes, seconds.
nlohmann::ordered_json slice_stats_json(const slicer::SliceStats& stats,
                                        const SliceOptions& options, std::size_t bytes);

//! The `slice` report: `input`, `slice` (slice_stats_json), `seconds` {ingest, slice,
//! total}, `ingest`.
nlohmann::ordered_json slice_report(const Ingested& in, const slicer::SliceStats& stats,
                                    const SliceRequest& request, std::size_t bytes,
                                    double total_seconds);

}  // namespace stlrefine::api
