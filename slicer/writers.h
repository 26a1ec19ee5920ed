// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Contour formats, streamed layer by layer: JSON, SVG and CLI (Common Layer Interface 2.0,
// ASCII and binary). A writer is a set of pure functions: header (needs only the plan),
// one layer (called concurrently for different layers), footer (needs the totals). The
// driver encodes layers on the worker threads and hands the bytes to a sink in order, so
// neither side ever holds more than a few layers.

#include <atomic>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <string_view>

#include "core/io/atomic_file.h"
#include "slicer/slice.h"

namespace stlrefine::slicer {

enum class SliceFormat {
  Json,       //!< application/json
  Svg,        //!< image/svg+xml: one <g> per layer, holes cut out (fill-rule evenodd)
  CliAscii,   //!< Common Layer Interface 2.0, $$ASCII
  CliBinary,  //!< Common Layer Interface 2.0, $$BINARY (long commands, little-endian)
};

//! "json", "svg", "cli" (ASCII) or "cli-binary".
const char* to_string(SliceFormat format);
//! Inverse of to_string; also accepts "cli-ascii".
//! \throw Error(InvalidParameter, field "format") listing the accepted names.
SliceFormat parse_slice_format(std::string_view name);
//! Media type for an HTTP response.
const char* media_type(SliceFormat format);
//! ".json", ".svg" or ".cli".
const char* file_extension(SliceFormat format);

struct WriterOptions {
  //! Part name: JSON "name", SVG <title>, CLI $$LABEL text. Printable ASCII is kept; other
  //! bytes (and commas for CLI) become '_'. At most 256 bytes.
  std::string label = "part";
  //! CLI only: $$UNITS, millimetres per coordinate unit, [1e-6, 1e3]. Coordinates and
  //! heights are written divided by it.
  double cli_units = 1.0;

  //! \throw Error(InvalidParameter) naming the field.
  void validate() const;
};

//! One output format. Every method is const and keeps no state, so layer() may run on
//! several threads at once.
class LayerWriter {
 public:
  virtual ~LayerWriter() = default;
  virtual SliceFormat format() const = 0;
  //! Everything before the first layer.
  virtual void header(const SlicePlan& plan, std::string& out) const = 0;
  //! One layer (appended to out). Layers are written with every index from 0 to
  //! plan.heights.size() - 1, empty ones too.
  virtual void layer(const Layer& layer, std::string& out) const = 0;
  //! Everything after the last layer.
  virtual void footer(const SliceStats& stats, std::string& out) const = 0;
};

//! \throw Error(InvalidParameter) when the options are out of range.
std::unique_ptr<LayerWriter> make_writer(SliceFormat format, const WriterOptions& options = {});

//! What one layer costs in `format` against SliceParams::max_points, whatever it holds: the
//! bytes of an empty layer's record (with a 6-digit index and a 23-character height) over
//! the fewest bytes one more contour point takes in that format (",[0,0]" in JSON, "L0 0"
//! in SVG, ",0,0" in CLI, 8 bytes in binary CLI), rounded up: 20 for JSON, 42 for SVG, 8
//! for CLI and 1 for binary CLI. A million empty SVG layers (140 MB) count as 42 million
//! points, over the daemon's default cap.
std::uint64_t empty_layer_points(SliceFormat format);

//! Receives the output bytes in order; may throw to abort (the error propagates).
using stlrefine::ByteSink;  // core/io/atomic_file.h

//! Slices `mesh` and streams the encoded result to `sink`: header, every layer in order,
//! footer. Memory stays bounded by the layers in flight, whatever the part's height.
//! Each layer costs at least empty_layer_points(writer.format()) against max_points
//! (params.points_per_layer when that is larger), checked before anything is written.
//! \throw as slice(), plus whatever the sink throws.
SliceStats write_slices(const Mesh& mesh, const SliceParams& params, const LayerWriter& writer,
                        const ByteSink& sink, const ProgressFn& progress = {},
                        const std::atomic<bool>* cancel = nullptr);

//! write_slices into one string (HTTP responses, tests).
std::string write_slices_to_string(const Mesh& mesh, const SliceParams& params,
                                   const LayerWriter& writer, SliceStats* stats = nullptr);

//! write_slices to a temporary file next to `path`, then fsync and rename: a failed or
//! cancelled run never leaves a partial file.
//! \throw Error(InvalidParameter, field "path") when the file cannot be created;
//! Error(Internal) when writing fails midway; and as write_slices.
SliceStats write_slices_file(const std::filesystem::path& path, const Mesh& mesh,
                             const SliceParams& params, const LayerWriter& writer,
                             const ProgressFn& progress = {},
                             const std::atomic<bool>* cancel = nullptr);

}  // namespace stlrefine::slicer
