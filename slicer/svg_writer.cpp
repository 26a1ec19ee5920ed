// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// SVG: one file, one <g id="layer-K"> per layer, all stacked on the part's xy footprint
// (seen from +z: each group flips y). A layer's loops are one <path> with fill-rule evenodd,
// so holes show as holes; open polylines are red <polyline>s. Opened in a browser the stack
// reads as an X-ray of the part; FILE.svg#layer-K shows layer K alone (CSS :target), and
// Inkscape lists every layer (inkscape:groupmode="layer") to toggle by hand.

#include <algorithm>
#include <string>

#include "slicer/writer_util.h"

namespace stlrefine::slicer::detail {

namespace {

class SvgWriter final : public LayerWriter {
 public:
  explicit SvgWriter(const WriterOptions& options)
      : label_(sanitize_label(options.label, "<>&\"'")) {}

  SliceFormat format() const override { return SliceFormat::Svg; }

  void header(const SlicePlan& plan, std::string& out) const override {
    double x = 0, y = 0, w = 1, h = 1;
    if (!plan.bounds.empty) {
      const Vec3 &a = plan.bounds.min, &b = plan.bounds.max;
      const double margin = std::max(0.02 * std::max(b.x - a.x, b.y - a.y), 0.5);
      x = a.x - margin;
      y = -b.y - margin;  // y is flipped by each layer's transform
      w = b.x - a.x + 2 * margin;
      h = b.y - a.y + 2 * margin;
    }
    out += "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n";
    out +=
        "<svg xmlns=\"http://www.w3.org/2000/svg\" "
        "xmlns:inkscape=\"http://www.inkscape.org/namespaces/inkscape\" version=\"1.1\" width=\"";
    append_number(out, w);
    out += "mm\" height=\"";
    append_number(out, h);
    out += "mm\" viewBox=\"";
    for (double v : {x, y, w, h}) append_number(out, v), out += ' ';
    out.back() = '"';
    out += ">\n<title>";
    out += label_;
    out += ": ";
    append_uint(out, plan.heights.size());
    out += " layers (mm, seen from +z)</title>\n";
    out +=
        "<style>\n"
        ".layer path{fill:#3b78d8;fill-opacity:0.12;fill-rule:evenodd;stroke:#1d3c6e;"
        "stroke-opacity:0.5;stroke-width:0.5px;vector-effect:non-scaling-stroke}\n"
        ".layer polyline{fill:none;stroke:#d0342c;stroke-width:1px;"
        "vector-effect:non-scaling-stroke}\n"
        "svg:has(.layer:target) .layer:not(:target){display:none}\n"
        ".layer:target path{fill-opacity:0.6;stroke-opacity:1}\n"
        "</style>\n";
  }

  void layer(const Layer& layer, std::string& out) const override {
    out += "<g id=\"layer-";
    append_uint(out, layer.index);
    out += "\" class=\"layer\" inkscape:groupmode=\"layer\" inkscape:label=\"z ";
    append_number(out, layer.z);
    out += "\" data-z=\"";
    append_number(out, layer.z);
    out += "\" transform=\"scale(1,-1)\">";
    if (!layer.loops.empty()) {
      out += "\n<path d=\"";
      for (const Loop& l : layer.loops) {
        char cmd = 'M';
        for (const Point2& p : l.points) {
          out += cmd;
          append_number(out, p.x);
          out += ' ';
          append_number(out, p.y);
          cmd = 'L';
        }
        out += 'Z';
      }
      out += "\"/>";
    }
    for (const Polyline& p : layer.open) {
      out += "\n<polyline points=\"";
      for (const Point2& q : p.points) {
        append_number(out, q.x);
        out += ',';
        append_number(out, q.y);
        out += ' ';
      }
      if (!p.points.empty()) out.pop_back();
      out += "\"/>";
    }
    out += "</g>\n";
  }

  void footer(const SliceStats&, std::string& out) const override { out += "</svg>\n"; }

 private:
  std::string label_;
};

}  // namespace

std::unique_ptr<LayerWriter> make_svg_writer(const WriterOptions& options) {
  return std::make_unique<SvgWriter>(options);
}

}  // namespace stlrefine::slicer::detail
