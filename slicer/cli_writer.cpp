// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// Common Layer Interface (CLI) 2.0, the layer format of SLS/SLM machines. Sources used:
// the CLI 2.0 specification (as archived from cranfield.ac.uk/aero/rapid/CLI/cli_v20.html
// and cited by readers), cross-checked against two independent open readers/writers
// (Digital-Production-Aachen/OpenVectorFormatTools CliFileAccess.cs, Shapeways abfab3d
// CLISliceReader.java); nothing copied.
//
// Header (ASCII in both variants, one command per line):
//   $$HEADERSTART / $$ASCII or $$BINARY / $$UNITS/u (mm per unit) / $$VERSION/200 /
//   $$LABEL/1,name / $$DIMENSION/x1,y1,z1,x2,y2,z2 / $$LAYERS/n / $$HEADEREND
// ASCII geometry:
//   $$GEOMETRYSTART, then per layer $$LAYER/z and $$POLYLINE/id,dir,n,p1x,p1y,...,pnx,pny,
//   then $$GEOMETRYEND. dir: 1 counter-clockwise (outer), 0 clockwise (hole), 2 open;
//   a closed loop repeats its first point (n counts it).
// Binary geometry: follows "$$HEADEREND" immediately (no line break, no GEOMETRYSTART/END),
//   a sequence of commands, each a 16-bit unsigned command index then its parameters, all
//   little-endian; "long" commands are used (32-bit integers, IEEE 754 single reals), so
//   coordinates need no quantisation and may be negative:
//     127 Start Layer (long):    z: real
//     130 Start PolyLine (long): id: long, dir: long, n: long, then n x (x: real, y: real)
//   (The short forms, 128 and 129, store 16-bit unsigned integers in units: they cannot
//   hold negative coordinates and quantise to `units`, so we do not write them.)
// Coordinates and heights are written divided by $$UNITS.

#include <bit>
#include <cstdint>
#include <cstring>
#include <string>

#include "slicer/writer_util.h"

namespace stlrefine::slicer::detail {

namespace {

static_assert(std::endian::native == std::endian::little,
              "the binary writer assumes little-endian");

constexpr std::uint16_t kStartLayerLong = 127;
constexpr std::uint16_t kStartPolylineLong = 130;
constexpr int kLabelId = 1;
enum Dir : std::int32_t { Clockwise = 0, CounterClockwise = 1, Open = 2 };

template <class T>
void put(std::string& out, T value) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  out.append(bytes, sizeof(T));
}

class CliWriter final : public LayerWriter {
 public:
  CliWriter(const WriterOptions& options, bool binary)
      : label_(sanitize_label(options.label, ",/$")), units_(options.cli_units), binary_(binary) {}

  SliceFormat format() const override {
    return binary_ ? SliceFormat::CliBinary : SliceFormat::CliAscii;
  }

  void header(const SlicePlan& plan, std::string& out) const override {
    out += "$$HEADERSTART\n";
    out += binary_ ? "$$BINARY\n" : "$$ASCII\n";
    out += "$$UNITS/";
    append_fixed(out, units_);
    out += "\n$$VERSION/200\n$$LABEL/";
    append_uint(out, kLabelId);
    out += ',';
    out += label_;
    out += '\n';
    if (!plan.bounds.empty) {
      const Vec3 &a = plan.bounds.min, &b = plan.bounds.max;
      out += "$$DIMENSION/";
      for (double v : {a.x, a.y, a.z, b.x, b.y, b.z}) append_fixed(out, v / units_), out += ',';
      out.back() = '\n';
    }
    out += "$$LAYERS/";
    append_uint(out, plan.heights.size());
    out += binary_ ? "\n$$HEADEREND" : "\n$$HEADEREND\n$$GEOMETRYSTART\n";
  }

  void layer(const Layer& layer, std::string& out) const override {
    if (binary_) {
      put(out, kStartLayerLong);
      put(out, float(layer.z / units_));
      for (const Loop& l : layer.loops)
        binary_polyline(out, l.points, l.kind == LoopKind::Outer ? CounterClockwise : Clockwise);
      for (const Polyline& p : layer.open) binary_polyline(out, p.points, Open);
      return;
    }
    out += "$$LAYER/";
    append_fixed(out, layer.z / units_);
    out += '\n';
    for (const Loop& l : layer.loops)
      ascii_polyline(out, l.points, l.kind == LoopKind::Outer ? CounterClockwise : Clockwise);
    for (const Polyline& p : layer.open) ascii_polyline(out, p.points, Open);
  }

  void footer(const SliceStats&, std::string& out) const override {
    if (!binary_) out += "$$GEOMETRYEND\n";
  }

 private:
  void ascii_polyline(std::string& out, const std::vector<Point2>& pts, Dir dir) const {
    const bool closed = dir != Open;
    out += "$$POLYLINE/";
    append_uint(out, kLabelId);
    out += ',';
    append_uint(out, std::size_t(dir));
    out += ',';
    append_uint(out, pts.size() + (closed ? 1 : 0));
    const auto point = [&](const Point2& p) {
      out += ',';
      append_fixed(out, p.x / units_);
      out += ',';
      append_fixed(out, p.y / units_);
    };
    for (const Point2& p : pts) point(p);
    if (closed && !pts.empty()) point(pts.front());
    out += '\n';
  }

  void binary_polyline(std::string& out, const std::vector<Point2>& pts, Dir dir) const {
    const bool closed = dir != Open;
    put(out, kStartPolylineLong);
    put(out, std::int32_t(kLabelId));
    put(out, std::int32_t(dir));
    put(out, std::int32_t(pts.size() + (closed ? 1 : 0)));
    const auto point = [&](const Point2& p) {
      put(out, float(p.x / units_));
      put(out, float(p.y / units_));
    };
    for (const Point2& p : pts) point(p);
    if (closed && !pts.empty()) point(pts.front());
  }

  std::string label_;
  double units_;
  bool binary_;
};

}  // namespace

std::unique_ptr<LayerWriter> make_cli_writer(const WriterOptions& options, bool binary) {
  return std::make_unique<CliWriter>(options, binary);
}

}  // namespace stlrefine::slicer::detail
