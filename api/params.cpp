// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "api/params.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>
#include <set>
#include <system_error>

#include "core/error.h"

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

const std::vector<std::string_view>& info_param_names() {
  static const std::vector<std::string_view> kNames{"crease_angle", "weld_tolerance"};
  return kNames;
}

std::vector<std::string_view> refine_param_names(const RequestLimits& limits) {
  std::vector<std::string_view> names{
      "scheme",         "levels",       "crease_angle", "max_faces",      "weld_tolerance",
      "adaptive_tol",   "max_level",    "slice",        "slice_format",   "alpha",
      "alpha_features", "kappa",        "ramp_steps",   "adaptive_angle", "primitives",
      "primitive_tol",  "max_deviation"};
  if (limits.accept_threads) names.push_back("threads");
  return names;
}

std::vector<std::string_view> slice_param_names(const RequestLimits& limits) {
  std::vector<std::string_view> names{"layer_height", "format",     "z_min",         "z_max",
                                      "heights",      "max_layers", "weld_tolerance"};
  if (limits.accept_threads) names.push_back("threads");
  return names;
}

SliceRequest parse_slice_params(const RawParams& params, const RequestLimits& limits) {
  check_names(params, slice_param_names(limits));
  SliceRequest request;
  slicer::SliceParams& p = request.slice.params;
  const std::size_t cap = p.max_layers;
  p.max_points = limits.max_slice_points;
  for (const auto& [name, value] : params) {
    if (name == "layer_height") {
      p.layer_height = parse_number(name, value);
    } else if (name == "format") {
      request.slice.format = slicer::parse_slice_format(value);
    } else if (name == "z_min") {
      p.z_min = parse_number(name, value);
    } else if (name == "z_max") {
      p.z_max = parse_number(name, value);
    } else if (name == "heights") {
      p.heights = parse_heights(name, value);
    } else if (name == "max_layers") {
      p.max_layers = static_cast<std::size_t>(parse_unsigned(name, value, 1, cap));
    } else if (name == "threads") {
      p.threads = parse_int(name, value);
    } else if (name == "weld_tolerance") {
      request.weld_tolerance = parse_weld_tolerance(value);
    }
  }
  // Every layer is written, empty or not: its record counts against the point budget.
  p.points_per_layer = slicer::empty_layer_points(request.slice.format);
  // The ranges live in the slicer (SliceParams::validate), which names the same fields.
  p.validate();
  return request;
}

InfoRequest parse_info_params(const RawParams& params) {
  check_names(params, info_param_names());
  InfoRequest request;
  for (const auto& [name, value] : params) {
    if (name == "crease_angle") {
      parse_crease_angle(value, request.features);
    } else if (name == "weld_tolerance") {
      request.weld_tolerance = parse_weld_tolerance(value);
    }
  }
  request.features.validate();
  return request;
}

RefineRequest parse_refine_params(const RawParams& params, const RequestLimits& limits) {
  check_names(params, refine_param_names(limits));
  RefineRequest request;
  RefineParams& p = request.refine;
  p.max_faces = limits.default_max_faces != 0 ? std::min(limits.default_max_faces, limits.max_faces)
                                              : limits.max_faces;
  for (const auto& [name, value] : params) {
    if (name == "scheme") {
      p.scheme = value;
    } else if (name == "levels") {
      p.levels = parse_int(name, value);
    } else if (name == "crease_angle") {
      parse_crease_angle(value, p.features);
    } else if (name == "max_faces") {
      p.max_faces = parse_unsigned(name, value, 1, std::numeric_limits<std::uint64_t>::max());
      if (p.max_faces > limits.max_faces)
        throw invalid(name, "above_server_cap",
                      "max_faces = " + value + " is above this server's cap of " +
                          std::to_string(limits.max_faces) + " (a request may only lower it)");
    } else if (name == "threads") {
      p.threads = parse_int(name, value);
    } else if (name == "weld_tolerance") {
      request.weld_tolerance = parse_weld_tolerance(value);
    } else if (name == "adaptive_tol") {
      p.adaptive_tol = parse_number(name, value);
    } else if (name == "adaptive_angle") {
      p.adaptive_angle = parse_number(name, value);
    } else if (name == "max_level") {
      p.max_level = parse_int(name, value);
    } else if (name == "alpha") {
      p.alpha = parse_number(name, value);
    } else if (name == "alpha_features") {
      p.alpha_features = parse_number(name, value);
    } else if (name == "kappa") {
      p.kappa = parse_number(name, value);
    } else if (name == "ramp_steps") {
      p.ramp_steps = parse_int(name, value);
    } else if (name == "primitives") {
      if (value != "auto" && value != "off")
        throw invalid(name, "unknown_value",
                      "primitives = " + shown(value) + " is not one of auto, off");
      request.primitives.enabled = value == "auto";
    } else if (name == "primitive_tol") {
      const double t = parse_number(name, value);
      if (!(t > 0 && t <= 1e-2))
        throw invalid(name, "out_of_range",
                      "primitive_tol = " + shown(value) +
                          " is outside (0, 0.01] (a fraction of the bounding box diagonal)");
      request.primitives.tolerance = t;
    } else if (name == "max_deviation") {
      request.primitives.max_deviation_given = true;
      request.primitives.measure = value != "off";
      if (value == "off") {
        request.primitives.max_deviation = 0;
      } else if (value != "auto") {
        const double d = parse_number(name, value);
        if (!(d >= 0 && d <= 1e6))
          throw invalid(name, "out_of_range",
                        "max_deviation = " + shown(value) +
                            " is outside [0, 1e6] mm (0 = no bound; auto = the local default; "
                            "off = not even measured)");
        request.primitives.max_deviation = d;
      }
    } else if (name == "slice") {
      if (!request.slice) request.slice.emplace();
      request.slice->params.layer_height = parse_number(name, value);
    } else if (name == "slice_format") {
      if (!request.slice) request.slice.emplace();
      try {
        request.slice->format = slicer::parse_slice_format(value);
      } catch (const Error& e) {
        throw renamed(e, "format", "slice_format");
      }
    }
  }
  if (request.slice) {
    const bool has_height = std::any_of(params.begin(), params.end(),
                                        [](const auto& kv) { return kv.first == "slice"; });
    if (!has_height)
      throw invalid("slice_format", "missing_parameter",
                    "slice_format needs slice (the layer height in mm)");
    request.slice->params.threads = p.threads;
    request.slice->params.max_points = limits.max_slice_points;
    request.slice->params.points_per_layer = slicer::empty_layer_points(request.slice->format);
    try {
      request.slice->params.validate();
    } catch (const Error& e) {
      throw renamed(e, "layer_height", "slice");
    }
  }
  // The ranges live in core (RefineParams::validate); this names the same fields.
  p.validate();
  return request;
}

}  // namespace stlrefine::api
