// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// JSON, written by hand (no JSON library in slicer/): the stream is one object whose
// "layers" array grows layer by layer. Numbers are shortest round-trip doubles.
//
//   {"format":"stlrefine-slices","version":1,"units":"mm","name":"part",
//    "layer_height":0.1,"bounds":{"min":[x,y,z],"max":[x,y,z]},"layer_count":n,
//    "layers":[
//     {"index":0,"z":0.05,"area":..,"degenerate_loops":0,"reversed_loops":0,
//      "polygons":[{"type":"outer","depth":0,"parent":null,"area":..,"points":[[x,y],..]},
//                  {"type":"hole","depth":1,"parent":0,...}],
//      "open":[{"points":[[x,y],..]}]},
//     ...],
//    "summary":{"layers":n,"outer_loops":..,"holes":..,"open_polylines":..,"points":..,
//               "degenerate_loops":..,"reversed_loops":..}}

#include <string>

#include "slicer/writer_util.h"

namespace stlrefine::slicer::detail {

namespace {

void append_points(std::string& out, const std::vector<Point2>& pts) {
  out += '[';
  for (std::size_t i = 0; i < pts.size(); ++i) {
    if (i) out += ',';
    out += '[';
    append_number(out, pts[i].x);
    out += ',';
    append_number(out, pts[i].y);
    out += ']';
  }
  out += ']';
}

class JsonWriter final : public LayerWriter {
 public:
  explicit JsonWriter(const WriterOptions& options)
      : label_(sanitize_label(options.label, "\"\\")) {}

  SliceFormat format() const override { return SliceFormat::Json; }

  void header(const SlicePlan& plan, std::string& out) const override {
    out += R"({"format":"stlrefine-slices","version":1,"units":"mm","name":")";
    out += label_;
    out += R"(","layer_height":)";
    if (plan.layer_height > 0)
      append_number(out, plan.layer_height);
    else
      out += "null";
    out += R"(,"bounds":)";
    if (plan.bounds.empty) {
      out += "null";
    } else {
      const Vec3 &a = plan.bounds.min, &b = plan.bounds.max;
      out += R"({"min":[)";
      for (double v : {a.x, a.y, a.z}) append_number(out, v), out += ',';
      out.back() = ']';
      out += R"(,"max":[)";
      for (double v : {b.x, b.y, b.z}) append_number(out, v), out += ',';
      out.back() = ']';
      out += '}';
    }
    out += R"(,"layer_count":)";
    append_uint(out, plan.heights.size());
    out += R"(,"layers":[)";
  }

  void layer(const Layer& layer, std::string& out) const override {
    out += layer.index == 0 ? "\n" : ",\n";
    out += R"({"index":)";
    append_uint(out, layer.index);
    out += R"(,"z":)";
    append_number(out, layer.z);
    out += R"(,"area":)";
    append_number(out, layer.area);
    out += R"(,"degenerate_loops":)";
    append_uint(out, layer.degenerate_loops);
    out += R"(,"reversed_loops":)";
    append_uint(out, layer.reversed_loops);
    out += R"(,"polygons":[)";
    for (std::size_t i = 0; i < layer.loops.size(); ++i) {
      const Loop& l = layer.loops[i];
      if (i) out += ',';
      out += R"({"type":")";
      out += to_string(l.kind);
      out += R"(","depth":)";
      append_uint(out, std::size_t(l.depth));
      out += R"(,"parent":)";
      if (l.parent < 0)
        out += "null";
      else
        append_uint(out, std::size_t(l.parent));
      out += R"(,"area":)";
      append_number(out, l.area);
      out += R"(,"points":)";
      append_points(out, l.points);
      out += '}';
    }
    out += R"(],"open":[)";
    for (std::size_t i = 0; i < layer.open.size(); ++i) {
      if (i) out += ',';
      out += R"({"points":)";
      append_points(out, layer.open[i].points);
      out += '}';
    }
    out += "]}";
  }

  void footer(const SliceStats& s, std::string& out) const override {
    out += "\n],\"summary\":{";
    const std::pair<const char*, std::uint64_t> fields[] = {
        {"layers", s.layers},
        {"outer_loops", s.outer_loops},
        {"holes", s.holes},
        {"open_polylines", s.open_polylines},
        {"points", s.points},
        {"degenerate_loops", s.degenerate_loops},
        {"reversed_loops", s.reversed_loops}};
    for (const auto& [name, value] : fields) {
      out += '"';
      out += name;
      out += "\":";
      append_uint(out, value);
      out += ',';
    }
    out.back() = '}';
    out += "}\n";
  }

 private:
  std::string label_;
};

}  // namespace

std::unique_ptr<LayerWriter> make_json_writer(const WriterOptions& options) {
  return std::make_unique<JsonWriter>(options);
}

}  // namespace stlrefine::slicer::detail
