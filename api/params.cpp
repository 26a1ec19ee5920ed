// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "api/params.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <iomanip>
#include <limits>
#include <set>
#include <sstream>
#include <system_error>

#include "api/param_table.h"
#include "core/error.h"
#include "core/schemes/registry.h"

namespace stlrefine::api {

namespace {

Error invalid(std::string_view field, std::string reason, const std::string& message) {
  return Error(ErrorCode::InvalidParameter, std::move(reason), message)
      .with_field(std::string(field));
}

// Values are echoed in messages; a query string may carry up to 8 KiB, so cut them short.
std::string shown(std::string_view text) {
  constexpr std::size_t kMax = 64;
  return "'" + std::string(text.substr(0, kMax)) + (text.size() > kMax ? "...'" : "'");
}

template <class T>
T parse_whole(std::string_view field, std::string_view text, const char* what) {
  T value{};
  const char* const end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, value);
  if (ec == std::errc::result_out_of_range)
    throw invalid(field, "out_of_range",
                  std::string(field) + " = " + shown(text) + " does not fit in " + what);
  if (text.empty() || ec != std::errc() || ptr != end)
    throw invalid(field, "not_a_number",
                  std::string(field) + " = " + shown(text) + " is not " + what);
  return value;
}

// Rejects names outside `allowed` and names given twice: a typo must never be ignored.
void check_names(const RawParams& params, const std::vector<std::string_view>& allowed) {
  std::set<std::string_view> seen;
  for (const auto& [name, value] : params) {
    if (std::find(allowed.begin(), allowed.end(), name) == allowed.end()) {
      std::string known;
      for (std::string_view n : allowed) known += (known.empty() ? "" : ", ") + std::string(n);
      throw invalid(name, "unknown_parameter",
                    "unknown parameter " + shown(name) + " (accepted: " + known + ")");
    }
    if (!seen.insert(name).second)
      throw invalid(name, "duplicate_parameter", "parameter '" + name + "' is given twice");
  }
}

// Any int: the range check is RefineParams::validate's, so the limits live in one place.
int parse_int(std::string_view field, std::string_view text) {
  return static_cast<int>(
      parse_integer(field, text, std::numeric_limits<int>::min(), std::numeric_limits<int>::max()));
}

// "0.1,0.2, 0.35": each item a complete number; empty items are refused.
std::vector<double> parse_heights(std::string_view field, std::string_view text) {
  std::vector<double> heights;
  std::size_t start = 0;
  for (;;) {
    const std::size_t comma = text.find(',', start);
    std::string_view item =
        text.substr(start, comma == std::string_view::npos ? text.npos : comma - start);
    while (!item.empty() && item.front() == ' ') item.remove_prefix(1);
    while (!item.empty() && item.back() == ' ') item.remove_suffix(1);
    heights.push_back(parse_number(field, item));
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  return heights;
}

// The same error with another field name: after a refinement the slice's layer height is
// the parameter `slice` and its format `slice_format`.
Error renamed(const Error& e, std::string_view from, std::string_view to) {
  if (e.field() != from) return e;
  Error out = e;
  out.with_field(std::string(to));
  return out;
}

int hex_digit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

// "%XX" -> the byte, '+' -> ' '; anything else (a lone '%' included) stays as it is, and
// the parameter parsers refuse what is then not a name or a number.
std::string url_decode(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (text[i] == '+') {
      out += ' ';
    } else if (text[i] == '%' && i + 2 < text.size() && hex_digit(text[i + 1]) >= 0 &&
               hex_digit(text[i + 2]) >= 0) {
      out += static_cast<char>(hex_digit(text[i + 1]) * 16 + hex_digit(text[i + 2]));
      i += 2;
    } else {
      out += text[i];
    }
  }
  return out;
}

double parse_scale(std::string_view text) {
  const double s = parse_number("scale", text);
  if (!(s > 0 && s <= 1e6))
    throw invalid("scale", "out_of_range", "scale = " + shown(text) + " is outside (0, 1e6]");
  return s;
}

double parse_weld_tolerance(std::string_view text) {
  const double t = parse_number("weld_tolerance", text);
  if (t < 0)
    throw invalid("weld_tolerance", "out_of_range",
                  "weld_tolerance = " + shown(text) + " must not be negative");
  return t;
}

}  // namespace

RawParams parse_query(std::string_view query) {
  RawParams params;
  std::size_t start = 0;
  while (start < query.size()) {
    const std::size_t amp = std::min(query.find('&', start), query.size());
    const std::string_view pair = query.substr(start, amp - start);
    start = amp + 1;
    if (pair.empty()) continue;
    const std::size_t eq = pair.find('=');
    std::string name = url_decode(pair.substr(0, eq));
    if (name.empty())
      throw invalid("query", "malformed_query",
                    "the query string has a parameter without a name: " + shown(pair));
    params.emplace_back(std::move(name), eq == std::string_view::npos
                                             ? std::string()
                                             : url_decode(pair.substr(eq + 1)));
  }
  return params;
}

long long parse_integer(std::string_view field, std::string_view text, long long lo, long long hi) {
  const long long value = parse_whole<long long>(field, text, "an integer");
  require_in_range(std::string(field).c_str(), value, lo, hi);
  return value;
}

std::uint64_t parse_unsigned(std::string_view field, std::string_view text, std::uint64_t lo,
                             std::uint64_t hi) {
  // from_chars accepts no sign for unsigned types, so "-1" is not_a_number, as it should be.
  const std::uint64_t value = parse_whole<std::uint64_t>(field, text, "a non-negative integer");
  require_in_range(std::string(field).c_str(), value, lo, hi);
  return value;
}

double parse_number(std::string_view field, std::string_view text) {
  // from_chars(double) reads "nan", "inf" and "infinity"; a parameter is never one.
  const double value = parse_whole<double>(field, text, "a number");
  if (!std::isfinite(value))
    throw invalid(field, "not_a_number",
                  std::string(field) + " = " + shown(text) + " is not a finite number");
  return value;
}

namespace {

// `crease_angle`: "auto" selects Auto detection (also the default when it is absent), a
// number Angle mode with that angle (the user's override, issue 17 item 5).
void parse_crease_angle(std::string_view text, FeatureParams& features) {
  if (text == "auto") {
    features.crease_mode = CreaseMode::Auto;
    return;
  }
  features.crease_angle_deg = parse_number("crease_angle", text);
  features.crease_mode = CreaseMode::Angle;
}

}  // namespace

namespace {

// --- the rows' readers

void refine_max_faces(RefineRequest& r, const std::string& value, const RequestLimits& limits) {
  r.refine.max_faces =
      parse_unsigned("max_faces", value, 1, std::numeric_limits<std::uint64_t>::max());
  if (r.refine.max_faces > limits.max_faces)
    throw invalid("max_faces", "above_server_cap",
                  "max_faces = " + value + " is above this server's cap of " +
                      std::to_string(limits.max_faces) + " (a request may only lower it)");
}

void refine_primitives(RefineRequest& r, const std::string& value, const RequestLimits&) {
  if (value != "auto" && value != "off")
    throw invalid("primitives", "unknown_value",
                  "primitives = " + shown(value) + " is not one of auto, off");
  r.primitives.enabled = value == "auto";
}

void refine_primitive_tol(RefineRequest& r, const std::string& value, const RequestLimits&) {
  const double t = parse_number("primitive_tol", value);
  if (!(t > 0 && t <= 1e-2))
    throw invalid("primitive_tol", "out_of_range",
                  "primitive_tol = " + shown(value) +
                      " is outside (0, 0.01] (a fraction of the bounding box diagonal)");
  r.primitives.tolerance = t;
}

void refine_max_deviation(RefineRequest& r, const std::string& value, const RequestLimits&) {
  r.primitives.max_deviation_given = true;
  r.primitives.measure = value != "off";
  if (value == "off") {
    r.primitives.max_deviation = 0;
  } else if (value != "auto") {
    const double d = parse_number("max_deviation", value);
    if (!(d >= 0 && d <= 1e6))
      throw invalid("max_deviation", "out_of_range",
                    "max_deviation = " + shown(value) +
                        " is outside [0, 1e6] mm (0 = no bound; auto = the local default; "
                        "off = not even measured)");
    r.primitives.max_deviation = d;
  }
}

// Slicing the refined mesh (/v1/refine, /v1/jobs) takes the names /v1/slice takes.
slicer::SliceParams& refine_slicing(RefineRequest& r) {
  if (!r.slice) r.slice.emplace();
  return r.slice->params;
}

void refine_slice(RefineRequest& r, const std::string& value, const RequestLimits&) {
  refine_slicing(r).layer_height = parse_number("slice", value);
  r.slice->layer_height_name = "slice";
}

void refine_slice_format(RefineRequest& r, const std::string& value, const RequestLimits&) {
  if (!r.slice) r.slice.emplace();
  try {
    r.slice->format = slicer::parse_slice_format(value);
  } catch (const Error& e) {
    throw renamed(e, "format", "slice_format");
  }
}

// Names kept for the scripts written before every route took the same names: on their
// route each means its replacement, and both at once is a conflict.
struct OldName {
  RequestKind kind;
  std::string_view name, replaced_by;
};
constexpr OldName kOldNames[] = {{RequestKind::Refine, "slice", "layer_height"},
                                 {RequestKind::Slice, "format", "slice_format"}};

// The old name the caller used on this route, if any (at most one per route today).
// \throw Error(InvalidParameter) naming the old name when its replacement is given too.
std::optional<std::string_view> check_aliases(const RawParams& params, RequestKind kind) {
  std::optional<std::string_view> used;
  const auto given = [&](std::string_view n) {
    return std::any_of(params.begin(), params.end(), [&](const auto& kv) { return kv.first == n; });
  };
  for (const OldName& old : kOldNames) {
    if (old.kind != kind || !given(old.name)) continue;
    if (given(old.replaced_by))
      throw invalid(old.name, "conflicting_parameters",
                    std::string(old.name) + " is the old name of " + std::string(old.replaced_by) +
                        ": give one of them");
    used = old.name;
  }
  return used;
}

// An error about a parameter named as the caller named it: the replacement's name becomes
// the old one when the caller used the old one.
Error in_callers_words(const Error& e, RequestKind kind, std::optional<std::string_view> old_name) {
  if (!old_name) return e;
  for (const OldName& old : kOldNames)
    if (old.kind == kind && old.name == *old_name) return renamed(e, old.replaced_by, old.name);
  return e;
}

repair::RepairMode parse_repair_mode(const std::string& value) {
  if (value == "none") return repair::RepairMode::None;
  if (value == "fill_holes") return repair::RepairMode::FillHoles;
  throw invalid("repair", "unknown_value",
                "repair = " + shown(value) + " is not one of none, fill_holes");
}

bool parse_report_place(const std::string& value) {
  if (value == "header") return false;
  if (value == "zip") return true;
  throw invalid("report", "unknown_value",
                "report = " + shown(value) + " is not one of header, zip");
}

// A request may only lower the default cap.
std::size_t max_layers_value(const std::string& v) {
  return static_cast<std::size_t>(
      parse_unsigned("max_layers", v, 1, slicer::SliceParams{}.max_layers));
}

void slice_slice_format(SliceRequest& r, const std::string& value) {
  try {
    r.slice.format = slicer::parse_slice_format(value);
  } catch (const Error& e) {
    throw renamed(e, "format", "slice_format");
  }
}

// `mesh_format`: the refined mesh's file format (`format` is the contour format of
// /v1/slice, and refine's contour format is `slice_format`; one name per meaning on every
// route).
void refine_mesh_format(RefineRequest& r, const std::string& value, const RequestLimits&) {
  if (value == "stl")
    r.mesh_format = MeshFormat::Stl;
  else if (value == "3mf")
    r.mesh_format = MeshFormat::ThreeMf;
  else
    throw invalid("mesh_format", "unknown_value",
                  "mesh_format = " + shown(value) + " is not one of stl, 3mf");
  r.mesh_format_given = true;
}

// The one table (param_table.h). Rows that only slicing takes come first, so that every
// request kind's names keep the order they have always been listed in.
const ParamRow kParams[] = {
    {.name = "layer_height",
     .type = ParamType::Number,
     .description = "Layer height in mm.",
     .help = "Layer thickness in mm; planes at z_min + (k + 1/2) h",
     .example = "0.5",
     .default_value = "0.1",
     .minimum = 1e-4,
     .maximum = 1e4,
     .refine =
         [](RefineRequest& r, const std::string& v, const RequestLimits&) {
           refine_slicing(r).layer_height = parse_number("layer_height", v);
         },
     .slice =
         [](SliceRequest& r, const std::string& v) {
           r.slice.params.layer_height = parse_number("layer_height", v);
         }},
    {.name = "format",
     .type = ParamType::String,
     .description = "Deprecated on /v1/slice: the same as slice_format.",
     .help = "Deprecated: use --slice-format",
     .example = "svg",
     .default_value = "json",
     .slice = [](SliceRequest& r,
                 const std::string& v) { r.slice.format = slicer::parse_slice_format(v); }},
    {.name = "z_min",
     .type = ParamType::Number,
     .description = "Lowest height to slice (mm); default the part's bottom.",
     .help = "Bottom of the uniform layers (mesh bottom)",
     .example = "0",
     .refine = [](RefineRequest& r, const std::string& v,
                  const RequestLimits&) { refine_slicing(r).z_min = parse_number("z_min", v); },
     .slice = [](SliceRequest& r,
                 const std::string& v) { r.slice.params.z_min = parse_number("z_min", v); }},
    {.name = "z_max",
     .type = ParamType::Number,
     .description = "Highest height to slice (mm); default the part's top.",
     .help = "Top of the uniform layers (mesh top)",
     .example = "1",
     .refine = [](RefineRequest& r, const std::string& v,
                  const RequestLimits&) { refine_slicing(r).z_max = parse_number("z_max", v); },
     .slice = [](SliceRequest& r,
                 const std::string& v) { r.slice.params.z_max = parse_number("z_max", v); }},
    {.name = "heights",
     .type = ParamType::String,
     .description = "Explicit comma-separated slice heights in mm.",
     .help = "Explicit plane heights a,b,c (replace the uniform layers)",
     .example = "0.5,1",
     .refine =
         [](RefineRequest& r, const std::string& v, const RequestLimits&) {
           refine_slicing(r).heights = parse_heights("heights", v);
         },
     .slice = [](SliceRequest& r,
                 const std::string& v) { r.slice.params.heights = parse_heights("heights", v); }},
    {.name = "max_layers",
     .type = ParamType::Integer,
     .description = "Refuse with 422 when the plan has more layers.",
     .help = "Refuse before any work above this many layers",
     .example = "100",
     .default_value = "1000000",
     .minimum = 1,
     .maximum = 1e6,
     .refine = [](RefineRequest& r, const std::string& v,
                  const RequestLimits&) { refine_slicing(r).max_layers = max_layers_value(v); },
     .slice = [](SliceRequest& r,
                 const std::string& v) { r.slice.params.max_layers = max_layers_value(v); }},
    {.name = "scheme",
     .type = ParamType::String,
     .description = "Subdivision scheme.",
     .help = "Subdivision scheme",
     .example = "loop",
     .default_value = "butterfly",
     .refine = [](RefineRequest& r, const std::string& v,
                  const RequestLimits&) { r.refine.scheme = v; }},
    {.name = "levels",
     .type = ParamType::Integer,
     .description = "Uniform subdivision steps, 0..8.",
     .help = "Subdivision steps",
     .example = "2",
     .default_value = "1",
     .minimum = 0,
     .maximum = 8,
     .refine = [](RefineRequest& r, const std::string& v,
                  const RequestLimits&) { r.refine.levels = parse_int("levels", v); }},
    {.name = "crease_angle",
     .type = ParamType::String,
     .description =
         "auto (default): creases found from the geometry; or a dihedral angle in degrees, "
         "0..180, above which an edge is a crease.",
     .help = "Sharp edges: auto (default: found from the geometry) or a dihedral angle in "
             "degrees above which an edge is sharp [0, 180]",
     .example = "30",
     .default_value = "auto",
     .refine = [](RefineRequest& r, const std::string& v,
                  const RequestLimits&) { parse_crease_angle(v, r.refine.features); },
     .info = [](InfoRequest& r, const std::string& v) { parse_crease_angle(v, r.features); }},
    {.name = "max_faces",
     .type = ParamType::Integer,
     .description = "Face budget of the output; refused with 422 before any work above it.",
     .help = "Refuse before any work if the output would have more faces (the daemon's "
             "default is its cap; the CLI's 20000000)",
     .example = "1000",
     .minimum = 1,
     .maximum = 2147483647,
     .refine = refine_max_faces},
    {.name = "weld_tolerance",
     .type = ParamType::Number,
     .description = "Distance below which STL corners are welded, in the file's units (before "
                    "units= converts them).",
     .help = "Merge corners closer than this (in the file's units, before units=; 0 = exact)",
     .example = "0.01",
     .default_value = "0",
     .minimum = 0,
     .refine = [](RefineRequest& r, const std::string& v,
                  const RequestLimits&) { r.weld_tolerance = parse_weld_tolerance(v); },
     .slice = [](SliceRequest& r,
                 const std::string& v) { r.weld_tolerance = parse_weld_tolerance(v); },
     .info = [](InfoRequest& r,
                const std::string& v) { r.weld_tolerance = parse_weld_tolerance(v); }},
    {.name = "units",
     .type = ParamType::String,
     .description =
         "What the file's numbers are in: mm, cm, m, in; auto (default) reads mm and flags a "
         "part whose size is implausible in mm (every extent under 1 mm, or one over 2 m) "
         "with a warning in the report, without converting it. The output is in mm.",
     .help = "What the file's numbers are in: mm, cm, m, in, or auto (read as mm; a part "
             "under 1 mm or over 2 m is flagged in the report, not converted); the output is "
             "in mm",
     .example = "m",
     .default_value = "auto",
     .refine = [](RefineRequest& r, const std::string& v,
                  const RequestLimits&) { r.units.units = parse_length_unit(v); },
     .slice = [](SliceRequest& r, const std::string& v) { r.units.units = parse_length_unit(v); },
     .info = [](InfoRequest& r, const std::string& v) { r.units.units = parse_length_unit(v); }},
    {.name = "scale",
     .type = ParamType::Number,
     .description = "Multiplies the part after the unit conversion.",
     .help = "Multiply the part by this after the unit conversion",
     .example = "2",
     .default_value = "1",
     .minimum = 0,
     .maximum = 1e6,
     .exclusive_minimum = true,
     .refine = [](RefineRequest& r, const std::string& v,
                  const RequestLimits&) { r.units.scale = parse_scale(v); },
     .slice = [](SliceRequest& r, const std::string& v) { r.units.scale = parse_scale(v); },
     .info = [](InfoRequest& r, const std::string& v) { r.units.scale = parse_scale(v); }},
    {.name = "report",
     .type = ParamType::String,
     .description =
         "Where the synchronous answer's report goes: header (default: the X-Stlrefine-Report "
         "header, compact JSON) or zip (an application/zip with the result and report.json, "
         "for clients that cannot read response headers). A sliced refinement is always a "
         "zip with report.json.",
     .help = "(HTTP only) header or zip",
     .example = "zip",
     .default_value = "header",
     .http_only = true,
     .refine = [](RefineRequest& r, const std::string& v,
                  const RequestLimits&) { r.report_in_zip = parse_report_place(v); },
     .slice = [](SliceRequest& r,
                 const std::string& v) { r.report_in_zip = parse_report_place(v); }},
    {.name = "repair",
     .type = ParamType::String,
     .description =
         "What to fix before refining or slicing: none (default), or fill_holes (close every "
         "open boundary with CGAL's hole filling: triangulated, refined to the rim's density, "
         "faired; holes with more than 10000 rim edges, or whose rim no Delaunay triangulation "
         "fills, stay open). The report says what was "
         "done.",
     .help = "none, or fill_holes: close the open boundaries (CGAL hole filling with fairing) "
             "before refining or slicing",
     .example = "fill_holes",
     .default_value = "none",
     .refine = [](RefineRequest& r, const std::string& v,
                  const RequestLimits&) { r.repair = parse_repair_mode(v); },
     .slice = [](SliceRequest& r, const std::string& v) { r.repair = parse_repair_mode(v); },
     .info = [](InfoRequest& r, const std::string& v) { r.repair = parse_repair_mode(v); }},
    {.name = "adaptive_tol",
     .type = ParamType::Number,
     .description =
         "Chordal tolerance in mm, 0..1e6: curvature-adaptive refinement until every new point "
         "is within it of its flat edge or triangle (lsf, butterfly, sqrt3 schemes).",
     .help = "Curvature-adaptive: refine where the new point leaves its flat edge or triangle "
             "by more than this (mm; lsf, butterfly, sqrt3 schemes; 0 = off)",
     .example = "0.1",
     .default_value = "0",
     .minimum = 0,
     .maximum = 1e6,
     .refine =
         [](RefineRequest& r, const std::string& v, const RequestLimits&) {
           r.refine.adaptive_tol = parse_number("adaptive_tol", v);
         }},
    {.name = "max_level",
     .type = ParamType::Integer,
     .description = "Level cap of the adaptive mode, 1..8.",
     .help = "Level cap of the adaptive mode",
     .example = "3",
     .default_value = "4",
     .minimum = 1,
     .maximum = 8,
     .refine = [](RefineRequest& r, const std::string& v,
                  const RequestLimits&) { r.refine.max_level = parse_int("max_level", v); }},
    {.name = "slice",
     .type = ParamType::Number,
     .description = "Deprecated: the same as layer_height.",
     .help = "Deprecated: use --layer-height",
     .example = "0.5",
     .minimum = 1e-4,
     .maximum = 1e4,
     .refine = refine_slice},
    {.name = "slice_format",
     .type = ParamType::String,
     .description = "Contour format of the slice: json, svg, cli, cli-binary.",
     .help = "Contour format: json, svg, cli, cli-binary",
     .example = "svg",
     .default_value = "json",
     .refine = refine_slice_format,
     .slice = slice_slice_format},
    {.name = "mesh_format",
     .type = ParamType::String,
     .description = "Refined mesh file: stl (binary STL, default) or 3mf (in millimetres, one "
                    "object per object of the input). Without it, Accept: model/3mf asks for 3mf.",
     .help = "Refined mesh file: stl (binary STL) or 3mf (mm, one object per input object; "
             "also chosen by an -o name ending in .3mf)",
     .example = "stl",  // every row's example goes beside `slice`, which 3mf does not
     .default_value = "stl",
     .refine = refine_mesh_format},
    {.name = "adaptive_angle",
     .type = ParamType::Number,
     .description =
         "Degrees, 0..180: curvature-adaptive refinement where the normals of neighbouring "
         "faces across a non-sharp edge differ by more (lsf, butterfly, sqrt3 schemes).",
     .help = "Curvature-adaptive: refine where neighbouring faces' normals differ by more than "
             "this across a non-sharp edge (degrees; 0 = off; with --adaptive-tol either "
             "refines)",
     .example = "0",
     .default_value = "0",
     .minimum = 0,
     .maximum = 180,
     .refine =
         [](RefineRequest& r, const std::string& v, const RequestLimits&) {
           r.refine.adaptive_angle = parse_number("adaptive_angle", v);
         }},
    {.name = "primitives",
     .type = ParamType::String,
     .description =
         "auto: recognise planes, spheres, cylinders, cones and tori on the input and put "
         "the new vertices of their regions exactly on them (where that turns faces over, the "
         "part is refined again without them and the report's primitives.withdrawn says so); "
         "off (default): do not.",
     .help = "auto: recognise planes, spheres, cylinders, cones and tori on the input and put "
             "the new vertices of their regions exactly on them (where that would turn faces, "
             "the part is refined again without them: see the report); off: do not",
     .example = "auto",
     .default_value = "off",
     .refine = refine_primitives},
    {.name = "primitive_tol",
     .type = ParamType::Number,
     .description =
         "A region is recognised when every input vertex lies within this fraction of the "
         "bounding box diagonal of the primitive, (0, 0.01], default 1e-6.",
     .help = "A region is recognised when every input vertex of it lies within this fraction "
             "of the bounding box diagonal of the primitive",
     .example = "0.00001",
     .default_value = "1e-06",
     .minimum = 0,
     .maximum = 0.01,
     .exclusive_minimum = true,
     .refine = refine_primitive_tol},
    {.name = "max_deviation",
     .type = ParamType::String,
     .description =
         "No output vertex farther than this (mm, 0..1e6) from the input surface: vertices "
         "are pulled back towards it and counted in the report. auto (default; interpolating "
         "schemes only, the others are measured): the input's local chordal error; 0 = no "
         "bound, only measured; off = neither bound nor measured (with primitives=off: no "
         "post-pass, its time and memory saved).",
     .help = "No output vertex farther than this from the input surface (mm, [0, 1e6]; 0 = "
             "no bound, only measured; auto = the input's local chordal error, the default "
             "for interpolating schemes; off = neither bound nor measured, the fastest)",
     .example = "0.01",
     .default_value = "auto",
     .refine = refine_max_deviation},
    {.name = "threads",
     .type = ParamType::Integer,
     .description = "Worker threads, 0..256 (0 = every core).",
     .help = "Worker threads (0 = every core)",
     .example = "1",
     .default_value = "0",
     .minimum = 0,
     .maximum = 256,
     .cli_only = true,
     .refine = [](RefineRequest& r, const std::string& v,
                  const RequestLimits&) { r.refine.threads = parse_int("threads", v); },
     .slice = [](SliceRequest& r,
                 const std::string& v) { r.slice.params.threads = parse_int("threads", v); }},
};

// A scheme option's row, made from its declaration in the registry.
ParamRow scheme_option_row(const SchemeOptionSpec& spec) {
  return {.name = spec.name,
          .type = spec.integer ? ParamType::Integer : ParamType::Number,
          .description = spec.description,
          .help = spec.help,
          .example = spec.example,
          .minimum = spec.minimum,
          .maximum = spec.maximum,
          .exclusive_minimum = spec.exclusive_minimum,
          .scheme_option = &spec};
}

// kParams, then every scheme's options.
const std::vector<ParamRow>& all_rows() {
  static const std::vector<ParamRow> rows = [] {
    std::vector<ParamRow> r(std::begin(kParams), std::end(kParams));
    for (const SchemeOptionSpec* spec : scheme_option_specs())
      r.push_back(scheme_option_row(*spec));
    return r;
  }();
  return rows;
}

// Shortest text that reads back as `value` ("0.5", "1e-06", "2147483647").
std::string number_text(double value) {
  std::ostringstream out;
  out << std::setprecision(10) << value;
  return out.str();
}

// A scheme option's value: a number (an integer where it is one), checked against its
// declaration.
double read_scheme_option(const SchemeOptionSpec& spec, std::string_view text) {
  const double value =
      spec.integer
          ? static_cast<double>(parse_integer(spec.name, text, std::numeric_limits<int>::min(),
                                              std::numeric_limits<int>::max()))
          : parse_number(spec.name, text);
  spec.check(value);
  return value;
}

std::vector<std::string_view> names_of(RequestKind kind, bool with_cli_only) {
  std::vector<std::string_view> names;
  for (const ParamRow& row : all_rows())
    // with_cli_only: the CLI's names (its own rows, not the daemon's).
    if (row.takes(kind) && (with_cli_only ? !row.http_only : !row.cli_only))
      names.push_back(row.name);
  return names;
}

}  // namespace

const char* to_string(ParamType type) {
  switch (type) {
    case ParamType::String:
      return "string";
    case ParamType::Number:
      return "number";
    case ParamType::Integer:
      return "integer";
  }
  return "string";
}

bool ParamRow::takes(RequestKind kind) const {
  switch (kind) {
    case RequestKind::Refine:
      return refine != nullptr || scheme_option != nullptr;
    case RequestKind::Slice:
      return slice != nullptr;
    case RequestKind::Info:
      return info != nullptr;
  }
  return false;
}

std::span<const ParamRow> param_table() {
  return all_rows();
}

std::string_view replaced_by(RequestKind kind, std::string_view name) {
  for (const OldName& old : kOldNames)
    if (old.kind == kind && old.name == name) return old.replaced_by;
  return {};
}

const ParamRow* find_param(std::string_view name) {
  for (const ParamRow& row : all_rows())
    if (row.name == name) return &row;
  return nullptr;
}

std::vector<std::string_view> schemes_using(std::string_view name) {
  std::vector<std::string_view> schemes;
  for (const SchemeEntry& entry : scheme_registry())
    for (const SchemeOptionSpec& option : entry.options)
      if (option.name == name) schemes.push_back(entry.name);
  return schemes;
}

std::string range_text(const ParamRow& row) {
  // Built with push_back / append: GCC 12's -Wrestrict misfires on short string literals.
  std::string text;
  if (row.minimum && row.maximum) {
    text.push_back(row.exclusive_minimum ? '(' : '[');
    text.append(number_text(*row.minimum)).append(", ").append(number_text(*row.maximum));
    text.push_back(']');
  } else if (row.minimum) {
    text.push_back('>');
    if (!row.exclusive_minimum) text.push_back('=');
    text.append(" ").append(number_text(*row.minimum));
  } else if (row.maximum) {
    text.append("<= ").append(number_text(*row.maximum));
  }
  return text;
}

std::string default_text(const ParamRow& row) {
  if (row.scheme_option) return number_text(row.scheme_option->default_value);
  return std::string(row.default_value);
}

std::string cli_help(const ParamRow& row) {
  std::string help(row.help);
  if (const std::string range = range_text(row); !range.empty()) help += " " + range;
  if (const std::string value = default_text(row); !value.empty()) help += " (" + value + ")";
  return help;
}

std::string cli_option(std::string_view name) {
  std::string option = "--" + std::string(name);
  for (char& c : option)
    if (c == '_') c = '-';
  return option;
}

const std::vector<std::string_view>& info_param_names() {
  static const std::vector<std::string_view> kNames = names_of(RequestKind::Info, false);
  return kNames;
}

std::vector<std::string_view> refine_param_names(const RequestLimits& limits) {
  return names_of(RequestKind::Refine, limits.accept_threads);
}

std::vector<std::string_view> slice_param_names(const RequestLimits& limits) {
  return names_of(RequestKind::Slice, limits.accept_threads);
}

SliceRequest parse_slice_params(const RawParams& params, const RequestLimits& limits) {
  check_names(params, slice_param_names(limits));
  const std::optional<std::string_view> old_name = check_aliases(params, RequestKind::Slice);
  SliceRequest request;
  slicer::SliceParams& p = request.slice.params;
  p.max_points = limits.max_slice_points;
  try {
    for (const auto& [name, value] : params) find_param(name)->slice(request, value);
    // Every layer is written, empty or not: its record counts against the point budget.
    p.points_per_layer = slicer::empty_layer_points(request.slice.format);
    // The ranges live in the slicer (SliceParams::validate), which names the same fields.
    p.validate();
  } catch (const Error& e) {
    throw in_callers_words(e, RequestKind::Slice, old_name);
  }
  return request;
}

InfoRequest parse_info_params(const RawParams& params) {
  check_names(params, info_param_names());
  InfoRequest request;
  for (const auto& [name, value] : params) find_param(name)->info(request, value);
  request.features.validate();
  return request;
}

namespace {
RefineRequest read_refine_fields(const RawParams& params, const RequestLimits& limits);
}  // namespace

RefineRequest parse_refine_params(const RawParams& params, const RequestLimits& limits) {
  RefineRequest request = parse_refine_fields(params, limits);
  // The ranges live in core (RefineParams::validate); this names the same fields.
  request.refine.validate();
  return request;
}

RefineRequest parse_refine_fields(const RawParams& params, const RequestLimits& limits) {
  check_names(params, refine_param_names(limits));
  const std::optional<std::string_view> old_name = check_aliases(params, RequestKind::Refine);
  try {
    return read_refine_fields(params, limits);
  } catch (const Error& e) {
    throw in_callers_words(e, RequestKind::Refine, old_name);
  }
}

namespace {

RefineRequest read_refine_fields(const RawParams& params, const RequestLimits& limits) {
  RefineRequest request;
  RefineParams& p = request.refine;
  p.max_faces = limits.default_max_faces != 0 ? std::min(limits.default_max_faces, limits.max_faces)
                                              : limits.max_faces;
  for (const auto& [name, value] : params) {
    const ParamRow& row = *find_param(name);
    if (row.scheme_option)
      p.scheme_options.set(row.name, read_scheme_option(*row.scheme_option, value));
    else
      row.refine(request, value, limits);
  }
  if (request.slice) {
    // Slicing is asked for by a layer height or by explicit heights; the other slicing
    // names only modify it.
    const auto given = [&](std::string_view n) {
      return std::any_of(params.begin(), params.end(),
                         [&](const auto& kv) { return kv.first == n; });
    };
    if (!given("slice") && !given("layer_height") && !given("heights")) {
      std::string_view modifier = "slice_format";
      for (std::string_view n : {"slice_format", "z_min", "z_max", "max_layers"})
        if (given(n)) {
          modifier = n;
          break;
        }
      throw invalid(modifier, "missing_parameter",
                    std::string(modifier) +
                        " slices the refined mesh and needs layer_height (mm) or heights");
    }
    if (request.mesh_format == MeshFormat::ThreeMf)
      throw invalid("mesh_format", "unsupported_combination",
                    "mesh_format=3mf is for refine alone: refine + slice answers a zip with "
                    "the refined STL");
    request.slice->params.threads = p.threads;
    request.slice->params.max_points = limits.max_slice_points;
    request.slice->params.points_per_layer = slicer::empty_layer_points(request.slice->format);
    request.slice->params.validate();
  }
  return request;
}

}  // namespace

}  // namespace stlrefine::api
