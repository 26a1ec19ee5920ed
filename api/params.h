// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "api/units.h"
#include "core/features/features.h"
#include "core/io/mesh_formats.h"
#include "core/io/stl.h"
#include "core/refine.h"
#include "primitives/post_pass.h"
#include "repair/hole_filling.h"
#include "slicer/slice.h"
#include "slicer/writers.h"

namespace stlrefine::api {

//! Parameters as they arrive, by their API names (`crease_angle`, `max_faces`, ...), in
//! arrival order. Duplicates are kept so that they can be rejected.
using RawParams = std::vector<std::pair<std::string, std::string>>;

//! Limits the front end imposes on every request.
struct RequestLimits {
  //! The face cap. A request's `max_faces` may lower it, never raise it.
  std::uint64_t max_faces = 20'000'000;
  //! `max_faces` when the request gives none; 0 = the cap. (The daemon's default is its
  //! cap; the CLI's cap is the core's maximum and its default the core's default.)
  std::uint64_t default_max_faces = 0;
  //! Contour points one slice may produce (SliceParams::max_points), checked before the
  //! contour pass. The daemon lowers it: the answer is built in memory.
  std::uint64_t max_slice_points = slicer::SliceParams{}.max_points;
  //! Accept `threads` (the CLI does; the daemon decides threads itself).
  bool accept_threads = false;
};

//! What `info` needs besides the STL bytes.
struct InfoRequest {
  FeatureParams features;     //!< `crease_angle`: `auto` (default) or degrees [0, 180]
  double weld_tolerance = 0;  //!< `weld_tolerance`, the file's units, >= 0; 0 = exact welding
  UnitOptions units;          //!< `units`, `scale`
  repair::RepairMode repair = repair::RepairMode::None;  //!< `repair`: none, fill_holes
};

//! Planes and output format of a slice, alone (`slice`) or after a refinement.
struct SliceOptions {
  //! `layer_height` (also `slice`, its old name, after a refinement), `z_min`, `z_max`, `heights`
  //! (comma list), `max_layers` (may only lower the default cap), `threads` (CLI only).
  slicer::SliceParams params;
  slicer::SliceFormat format = slicer::SliceFormat::Json;  //!< `format` / `slice_format`
  slicer::WriterOptions writer;  //!< not a parameter: the CLI sets the label
  //! The name the caller gave the layer height: errors found later (no layer fits the
  //! part, too many layers) name the field as the caller knows it.
  std::string_view layer_height_name = "layer_height";
};

//! What `slice` needs besides the STL bytes.
struct SliceRequest {
  SliceOptions slice;
  bool report_in_zip = false;                            //!< `report`, as in RefineRequest
  double weld_tolerance = 0;                             //!< as in InfoRequest
  UnitOptions units;                                     //!< as in InfoRequest
  repair::RepairMode repair = repair::RepairMode::None;  //!< as in InfoRequest
};

//! The post-pass after refinement (issue 17 items 4 and 6): recognised primitives and the
//! deviation bound (primitives/).
struct PrimitiveOptions {
  //! `primitives`: auto recognises planes, spheres, cylinders, cones and tori on the input
  //! and puts the new vertices of their regions on them; off (the default) does not. Where
  //! the part refined with them turns faces over (thin faces along some rims: gearwheel,
  //! featuretype), the pipeline refines it again without them and says so in the report
  //! (api/pipeline.cpp). Still off by default: on the CAD-like torus that check (against the
  //! input's normals) misses a few faces folded against the truth (bench/RESULTS.md).
  bool enabled = false;
  //! `primitive_tol`: a region is recognised when every input vertex of it lies within this
  //! fraction of the bounding box diagonal of the primitive, (0, 1e-2], default 1e-6.
  double tolerance = 1e-6;
  //! `max_deviation`: mm, [0, 1e6], or `auto` (the default: the local sagitta of the input,
  //! see primitives::PostPassParams); 0 = no bound (the pass then only measures).
  std::optional<double> max_deviation;
  bool max_deviation_given = false;  //!< `max_deviation` was given (`auto` included)
  //! False for `max_deviation=off`: with primitives=off no post-pass at all (no bound, no
  //! measurement, none of its time and memory: the refinement as it was before the pass).
  bool measure = true;

  //! True when the post-pass runs: unless max_deviation=off with primitives=off, since
  //! max_deviation=auto is the default (it bounds interpolating schemes and measures the
  //! others for the report).
  bool post_pass() const { return enabled || measure; }
};

//! What `refine` needs besides the STL bytes.
struct RefineRequest {
  //! `scheme`, `levels`, `crease_angle`, `max_faces`, `threads`, `adaptive_tol`,
  //! `adaptive_angle`, `max_level`, and the schemes' options (`alpha`, `kappa`, ...: the
  //! registry's, into RefineParams::scheme_options)
  RefineParams refine;
  double weld_tolerance = 0;                             //!< as in InfoRequest
  UnitOptions units;                                     //!< as in InfoRequest
  repair::RepairMode repair = repair::RepairMode::None;  //!< as in InfoRequest
  StlFormat output_format = StlFormat::Binary;           //!< not a parameter: the CLI's --ascii
  //! `mesh_format`: stl (output_format says which kind) or 3mf. `mesh_format_given`: the
  //! request named it (else the daemon follows Accept: model/3mf).
  MeshFormat mesh_format = MeshFormat::Stl;
  bool mesh_format_given = false;
  //! `report`: header (default: X-Stlrefine-Report) or zip (the answer is a zip with the
  //! result and report.json, for clients that cannot read headers). Sliced answers are
  //! always zips with report.json.
  bool report_in_zip = false;
  //! `slice` (layer height, mm) and `slice_format`: also slice the refined mesh.
  std::optional<SliceOptions> slice;
  //! `primitives`, `primitive_tol`, `max_deviation`.
  PrimitiveOptions primitives;
};

//! The parameters of a URL query string ("scheme=loop&levels=%32"), in arrival order with
//! duplicates kept: '&' separates pairs (empty ones are skipped), the first '=' separates
//! the name from the value, and "%XX" and '+' (a space) are decoded in both; a pair without
//! '=' has an empty value. Nothing is dropped or merged, so "levels=1=2" is the value "1=2"
//! (not a number) and "levels=1&levels=1" is a duplicate, both refused by the parsers below.
//! \throw Error(InvalidParameter, "malformed_query", field "query") for a pair without a name.
RawParams parse_query(std::string_view query);

//! Names `parse_info_params` accepts.
const std::vector<std::string_view>& info_param_names();
//! Names `parse_refine_params` accepts (`threads` only with RequestLimits::accept_threads).
std::vector<std::string_view> refine_param_names(const RequestLimits& limits);

//! Parses and validates `info` parameters. Numbers must be complete and finite ("2x",
//! "", "1e400" and "nan" are rejected).
//! \throw Error(InvalidParameter) naming the field (reasons: unknown_parameter,
//! duplicate_parameter, not_a_number, out_of_range, unknown_scheme, above_server_cap).
InfoRequest parse_info_params(const RawParams& params);

//! Parses and validates `refine` parameters; absent ones keep their RefineParams
//! defaults, except `max_faces` (RequestLimits::default_max_faces). \throw Error(InvalidParameter)
//! as above.
RefineRequest parse_refine_params(const RawParams& params, const RequestLimits& limits);
//! parse_refine_params without RefineParams::validate (the slice options are validated):
//! for plan_refine, which validates them as it makes the scheme (make_scheme(RefineParams)).
RefineRequest parse_refine_fields(const RawParams& params, const RequestLimits& limits);

//! Names `parse_slice_params` accepts (`threads` only with RequestLimits::accept_threads).
std::vector<std::string_view> slice_param_names(const RequestLimits& limits);

//! Parses and validates `slice` parameters: `layer_height` (default 0.1), `format` (json,
//! svg, cli, cli-ascii, cli-binary; default json), `z_min`, `z_max`, `heights` (comma
//! separated, replaces the uniform layers), `max_layers`, `weld_tolerance`, `threads`.
//! \throw Error(InvalidParameter) naming the field, as above.
SliceRequest parse_slice_params(const RawParams& params, const RequestLimits& limits);

// --- the number parsers both functions use, exposed for the CLI and the tests

//! The whole of `text` as a decimal integer in [lo, hi].
//! \throw Error(InvalidParameter, "not_a_number" | "out_of_range") naming `field`.
long long parse_integer(std::string_view field, std::string_view text, long long lo, long long hi);
//! The whole of `text` as an unsigned decimal integer in [lo, hi].
std::uint64_t parse_unsigned(std::string_view field, std::string_view text, std::uint64_t lo,
                             std::uint64_t hi);
//! The whole of `text` as a finite decimal number ("nan", "inf" and overflow rejected).
double parse_number(std::string_view field, std::string_view text);

}  // namespace stlrefine::api
