// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "bench/fidelity/svg_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>
#include <tuple>

namespace stlrefine::fidelity {
namespace {

constexpr double kWidth = 900, kPanelHeight = 330, kTitleHeight = 40;
constexpr double kLeft = 70, kRight = 20, kTop = 30, kBottom = 45;

std::string fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f", v);
  return buf;
}

std::string tick_label(double v, double step) {
  char buf[32];
  const int digits = step >= 1 ? 0 : static_cast<int>(std::ceil(-std::log10(step)));
  std::snprintf(buf, sizeof buf, "%.*f", digits, std::abs(v) < 1e-12 ? 0.0 : v);
  return buf;
}

//! 1, 2 or 5 times a power of ten, giving about `count` ticks over `span`.
double nice_step(double span, int count) {
  const double raw = span / count;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0, 10.0})
    if (raw <= m * mag) return m * mag;
  return 10 * mag;
}

std::string escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c == '<')
      out += "&lt;";
    else if (c == '>')
      out += "&gt;";
    else if (c == '&')
      out += "&amp;";
    else
      out += c;
  }
  return out;
}

void draw_panel(std::ostream& svg, const Panel& panel, double y0) {
  const double left = kLeft, right = kWidth - kRight;
  const double top = y0 + kTop, bottom = y0 + kPanelHeight - kBottom;

  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const Series& s : panel.series)
    for (const auto& [x, y] : s.points) lo = std::min(lo, y), hi = std::max(hi, y);
  if (panel.reference_y)
    lo = std::min(lo, *panel.reference_y), hi = std::max(hi, *panel.reference_y);
  if (panel.y_range) std::tie(lo, hi) = *panel.y_range;
  if (!(hi > lo)) lo -= 1, hi += 1;
  const double pad = panel.y_range ? 0 : 0.05 * (hi - lo);
  lo -= pad, hi += pad;

  auto px = [&](double x) {
    return left + (x - panel.x_min) / (panel.x_max - panel.x_min) * (right - left);
  };
  auto py = [&](double y) { return bottom - (y - lo) / (hi - lo) * (bottom - top); };

  svg << "<text x=\"" << fmt(left) << "\" y=\"" << fmt(y0 + 18)
      << "\" font-size=\"14\" font-weight=\"bold\">" << escape(panel.title) << "</text>\n";
  // Grid and ticks.
  const double ys = nice_step(hi - lo, 6);
  for (double y = std::ceil(lo / ys) * ys; y <= hi + 1e-9 * ys; y += ys) {
    svg << "<line x1=\"" << fmt(left) << "\" x2=\"" << fmt(right) << "\" y1=\"" << fmt(py(y))
        << "\" y2=\"" << fmt(py(y)) << "\" stroke=\"#e6e6e6\"/>\n";
    svg << "<text x=\"" << fmt(left - 6) << "\" y=\"" << fmt(py(y) + 4)
        << "\" font-size=\"11\" text-anchor=\"end\">" << tick_label(y, ys) << "</text>\n";
  }
  const double xs = nice_step(panel.x_max - panel.x_min, 8);
  for (double x = std::ceil(panel.x_min / xs) * xs; x <= panel.x_max + 1e-9 * xs; x += xs) {
    svg << "<line x1=\"" << fmt(px(x)) << "\" x2=\"" << fmt(px(x)) << "\" y1=\"" << fmt(top)
        << "\" y2=\"" << fmt(bottom) << "\" stroke=\"#e6e6e6\"/>\n";
    svg << "<text x=\"" << fmt(px(x)) << "\" y=\"" << fmt(bottom + 16)
        << "\" font-size=\"11\" text-anchor=\"middle\">" << tick_label(x, xs) << "</text>\n";
  }
  svg << "<rect x=\"" << fmt(left) << "\" y=\"" << fmt(top) << "\" width=\"" << fmt(right - left)
      << "\" height=\"" << fmt(bottom - top) << "\" fill=\"none\" stroke=\"#444\"/>\n";
  svg << "<text x=\"" << fmt((left + right) / 2) << "\" y=\"" << fmt(bottom + 34)
      << "\" font-size=\"12\" text-anchor=\"middle\">" << escape(panel.x_label) << "</text>\n";
  svg << "<text transform=\"translate(" << fmt(18) << "," << fmt((top + bottom) / 2)
      << ") rotate(-90)\" font-size=\"12\" text-anchor=\"middle\">" << escape(panel.y_label)
      << "</text>\n";
  if (panel.reference_y)
    svg << "<line x1=\"" << fmt(left) << "\" x2=\"" << fmt(right) << "\" y1=\""
        << fmt(py(*panel.reference_y)) << "\" y2=\"" << fmt(py(*panel.reference_y))
        << "\" stroke=\"#888\" stroke-dasharray=\"2,3\"/>\n";

  // Data, clipped to the frame; points sorted by x so a wrapped loop draws left to right.
  svg << "<clipPath id=\"clip" << static_cast<int>(y0) << "\"><rect x=\"" << fmt(left) << "\" y=\""
      << fmt(top) << "\" width=\"" << fmt(right - left) << "\" height=\"" << fmt(bottom - top)
      << "\"/></clipPath>\n";
  double legend_y = top + 14;
  for (const Series& s : panel.series) {
    auto pts = s.points;
    std::sort(pts.begin(), pts.end());
    svg << "<polyline clip-path=\"url(#clip" << static_cast<int>(y0)
        << ")\" fill=\"none\" stroke=\"" << s.colour << "\" stroke-width=\"1.3\""
        << (s.dashed ? " stroke-dasharray=\"5,3\"" : "") << " points=\"";
    for (const auto& [x, y] : pts) svg << fmt(px(x)) << ',' << fmt(py(y)) << ' ';
    svg << "\"/>\n";
    svg << "<line x1=\"" << fmt(right - 230) << "\" x2=\"" << fmt(right - 205) << "\" y1=\""
        << fmt(legend_y - 4) << "\" y2=\"" << fmt(legend_y - 4) << "\" stroke=\"" << s.colour
        << "\" stroke-width=\"2\"" << (s.dashed ? " stroke-dasharray=\"5,3\"" : "") << "/>\n";
    svg << "<text x=\"" << fmt(right - 200) << "\" y=\"" << fmt(legend_y) << "\" font-size=\"11\">"
        << escape(s.label) << "</text>\n";
    legend_y += 15;
  }
}

}  // namespace

bool write_svg(const std::string& path, const std::string& title,
               const std::vector<Panel>& panels) {
  std::ostringstream svg;
  const double height = kTitleHeight + kPanelHeight * double(panels.size());
  svg << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << fmt(kWidth) << "\" height=\""
      << fmt(height) << "\" viewBox=\"0 0 " << fmt(kWidth) << ' ' << fmt(height)
      << "\" font-family=\"sans-serif\">\n";
  svg << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  svg << "<text x=\"" << fmt(kWidth / 2) << "\" y=\"26\" font-size=\"16\" text-anchor=\"middle\">"
      << escape(title) << "</text>\n";
  for (std::size_t i = 0; i < panels.size(); ++i)
    draw_panel(svg, panels[i], kTitleHeight + kPanelHeight * double(i));
  svg << "</svg>\n";
  std::ofstream out(path);
  out << svg.str();
  return static_cast<bool>(out);
}

}  // namespace stlrefine::fidelity
