// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "slicer/writers.h"

#include <algorithm>
#include <string>

#include "core/error.h"
#include "core/io/atomic_file.h"
#include "slicer/writer_util.h"

namespace stlrefine::slicer {

namespace {

struct FormatName {
  SliceFormat format;
  const char* name;
  const char* media;
  const char* extension;
};
constexpr FormatName kFormats[] = {
    {SliceFormat::Json, "json", "application/json", ".json"},
    {SliceFormat::Svg, "svg", "image/svg+xml", ".svg"},
    {SliceFormat::CliAscii, "cli", "text/plain; charset=us-ascii", ".cli"},
    {SliceFormat::CliBinary, "cli-binary", "application/octet-stream", ".cli"},
};

const FormatName& entry(SliceFormat format) {
  for (const FormatName& f : kFormats)
    if (f.format == format) return f;
  return kFormats[0];
}

}  // namespace

const char* to_string(SliceFormat format) {
  return entry(format).name;
}
const char* media_type(SliceFormat format) {
  return entry(format).media;
}
const char* file_extension(SliceFormat format) {
  return entry(format).extension;
}

SliceFormat parse_slice_format(std::string_view name) {
  for (const FormatName& f : kFormats)
    if (name == f.name) return f.format;
  if (name == "cli-ascii") return SliceFormat::CliAscii;
  throw Error(ErrorCode::InvalidParameter, "unknown_format",
              "format '" + std::string(name.substr(0, 64)) +
                  "' is not one of json, svg, cli, cli-ascii, cli-binary")
      .with_field("format");
}

void WriterOptions::validate() const {
  if (!(cli_units >= 1e-6 && cli_units <= 1e3)) {
    throw Error(ErrorCode::InvalidParameter, "out_of_range",
                "cli_units = " + std::to_string(cli_units) + " is outside [1e-6, 1e3] mm")
        .with_field("cli_units");
  }
  if (label.size() > 256) {
    throw Error(ErrorCode::InvalidParameter, "too_long", "label is longer than 256 bytes")
        .with_field("label");
  }
}

std::unique_ptr<LayerWriter> make_writer(SliceFormat format, const WriterOptions& options) {
  options.validate();
  switch (format) {
    case SliceFormat::Json:
      return detail::make_json_writer(options);
    case SliceFormat::Svg:
      return detail::make_svg_writer(options);
    case SliceFormat::CliAscii:
      return detail::make_cli_writer(options, false);
    case SliceFormat::CliBinary:
      return detail::make_cli_writer(options, true);
  }
  throw Error(ErrorCode::Internal, "unknown_format", "unknown slice format");
}

std::uint64_t empty_layer_points(SliceFormat format) {
  // The fewest bytes one more point adds (see the header).
  std::uint64_t point_bytes = 4;
  if (format == SliceFormat::Json) point_bytes = 6;
  if (format == SliceFormat::CliBinary) point_bytes = 8;
  Layer empty;
  empty.index = 999'999;  // max_layers is at most 1'000'000
  empty.z = -0.00012345678901234567;
  std::string record;
  make_writer(format)->layer(empty, record);
  return (record.size() + point_bytes - 1) / point_bytes;
}

SliceStats write_slices(const Mesh& mesh, const SliceParams& params, const LayerWriter& writer,
                        const ByteSink& sink, const ProgressFn& progress,
                        const std::atomic<bool>* cancel) {
  SliceParams charged = params;
  charged.points_per_layer = std::max(params.points_per_layer, empty_layer_points(writer.format()));
  const SlicePlan plan = plan_layers(mesh, charged);
  std::string text;
  SliceStats stats = detail::run(
      mesh, charged, plan,
      [&] {  // after the budget checks: nothing is written for a refused request
        writer.header(plan, text);
        sink(text);
      },
      [&](const Layer& layer, std::string& encoded) { writer.layer(layer, encoded); },
      [&](Layer&&, std::string&& encoded) { sink(encoded); }, progress, cancel);
  text.clear();
  writer.footer(stats, text);
  sink(text);
  return stats;
}

std::string write_slices_to_string(const Mesh& mesh, const SliceParams& params,
                                   const LayerWriter& writer, SliceStats* stats) {
  std::string out;
  const SliceStats s =
      write_slices(mesh, params, writer, [&](std::string_view bytes) { out.append(bytes); });
  if (stats) *stats = s;
  return out;
}

SliceStats write_slices_file(const std::filesystem::path& path, const Mesh& mesh,
                             const SliceParams& params, const LayerWriter& writer,
                             const ProgressFn& progress, const std::atomic<bool>* cancel) {
  SliceStats stats;
  write_file_atomically(path, [&](const ByteSink& sink) {
    stats = write_slices(mesh, params, writer, sink, progress, cancel);
  });
  return stats;
}

}  // namespace stlrefine::slicer
