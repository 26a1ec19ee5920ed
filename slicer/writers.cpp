// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "slicer/writers.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <string>
#include <system_error>

#include "core/error.h"
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

Error os_error(ErrorCode code, const char* reason, const std::string& what,
               const std::filesystem::path& path) {
  const std::string why = std::error_code(errno, std::generic_category()).message();
  return std::move(
      Error(code, reason, what + " '" + path.string() + "': " + why).with_field("path"));
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
  // A unique temporary name next to the target, so that rename() is atomic.
  static std::atomic<std::uint64_t> counter{0};
  std::filesystem::path tmp = path;
  tmp += ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(counter++);
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  if (fd < 0) throw os_error(ErrorCode::InvalidParameter, "cannot_create", "cannot create", tmp);

  SliceStats stats;
  try {
    // Layers arrive as separate strings; gather small ones to keep write(2) calls few.
    std::string buffer;
    const auto flush = [&] {
      const char* p = buffer.data();
      std::size_t left = buffer.size();
      while (left > 0) {
        const ssize_t n = ::write(fd, p, left);
        if (n < 0) {
          if (errno == EINTR) continue;
          throw os_error(ErrorCode::Internal, "write_failed", "cannot write", tmp);
        }
        p += n;
        left -= std::size_t(n);
      }
      buffer.clear();
    };
    stats = write_slices(
        mesh, params, writer,
        [&](std::string_view bytes) {
          buffer.append(bytes);
          if (buffer.size() >= (std::size_t{1} << 20)) flush();
        },
        progress, cancel);
    flush();
    if (::fsync(fd) != 0) throw os_error(ErrorCode::Internal, "write_failed", "cannot sync", tmp);
  } catch (...) {
    ::close(fd);
    ::unlink(tmp.c_str());
    throw;
  }
  if (::close(fd) != 0) {
    Error e = os_error(ErrorCode::Internal, "write_failed", "cannot close", tmp);
    ::unlink(tmp.c_str());
    throw e;
  }
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    Error e = os_error(ErrorCode::InvalidParameter, "cannot_create", "cannot replace", path);
    ::unlink(tmp.c_str());
    throw e;
  }
  return stats;
}

}  // namespace stlrefine::slicer
