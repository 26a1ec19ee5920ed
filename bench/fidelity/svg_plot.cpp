// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "bench/fidelity/svg_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace stlrefine::fidelity {
namespace {

constexpr double kTitleHeight = 40;
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

//! Tick positions (in plotted units) and their labels.
std::vector<std::pair<double, std::string>> linear_ticks(double lo, double hi, int count) {
  std::vector<std::pair<double, std::string>> ticks;
  const double step = nice_step(hi - lo, count);
  for (double v = std::ceil(lo / step) * step; v <= hi + 1e-9 * step; v += step)
    ticks.emplace_back(v, tick_label(v, step));
  return ticks;
}

std::string decade_label(double value) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", value);
  return buf;
}

//! On a log10 axis (lo, hi are log10 values): the decades, plus 2x and 5x when fewer than
//! three decades fall in the range.
std::vector<std::pair<double, std::string>> log_ticks(double lo, double hi) {
  std::vector<std::pair<double, std::string>> ticks;
  const int k0 = static_cast<int>(std::floor(lo)), k1 = static_cast<int>(std::ceil(hi));
  const bool fine = k1 - k0 < 4;
  for (int k = k0; k <= k1; ++k)
    for (const double m : {1.0, 2.0, 5.0}) {
      if (m != 1 && !fine) continue;
      const double v = std::log10(m) + k;
      if (v >= lo - 1e-9 && v <= hi + 1e-9)
        ticks.emplace_back(v, decade_label(m * std::pow(10.0, k)));
    }
  return ticks;
}

double axis_value(double v, bool log) {
  return log ? std::log10(v) : v;
}

void draw_panel(std::ostream& svg, const Panel& panel, double y0, const SvgLayout& layout) {
  const double left = kLeft, right = layout.width - kRight - layout.legend_width;
  const double top = y0 + kTop, bottom = y0 + layout.panel_height - kBottom;
  const bool lx = panel.log_x, ly = panel.log_y;
  const bool has_reference = panel.reference_y.has_value();
  const double reference = has_reference ? axis_value(*panel.reference_y, ly) : 0.0;
  const double x_min = axis_value(panel.x_min, lx), x_max = axis_value(panel.x_max, lx);

  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const Series& s : panel.series)
    for (const auto& [x, y] : s.points)
      lo = std::min(lo, axis_value(y, ly)), hi = std::max(hi, axis_value(y, ly));
  if (has_reference) lo = std::min(lo, reference), hi = std::max(hi, reference);
  if (panel.y_range)
    lo = axis_value(panel.y_range->first, ly), hi = axis_value(panel.y_range->second, ly);
  if (!(hi > lo)) lo -= 1, hi += 1;
  const double pad = panel.y_range ? 0 : 0.05 * (hi - lo);
  lo -= pad, hi += pad;

  auto px = [&](double x) { return left + (x - x_min) / (x_max - x_min) * (right - left); };
  auto py = [&](double y) { return bottom - (y - lo) / (hi - lo) * (bottom - top); };

  svg << "<text x=\"" << fmt(left) << "\" y=\"" << fmt(y0 + 18)
      << "\" font-size=\"14\" font-weight=\"bold\">" << escape(panel.title) << "</text>\n";
  // Grid and ticks; on a log axis also faint lines at 2..9 times each decade.
  auto minor = [](double a, double b, auto&& line) {
    for (int k = static_cast<int>(std::floor(a)); k <= static_cast<int>(std::ceil(b)); ++k)
      for (int m = 2; m <= 9; ++m) {
        const double v = std::log10(double(m)) + k;
        if (v > a && v < b) line(v);
      }
  };
  if (ly)
    minor(lo, hi, [&](double y) {
      svg << "<line x1=\"" << fmt(left) << "\" x2=\"" << fmt(right) << "\" y1=\"" << fmt(py(y))
          << "\" y2=\"" << fmt(py(y)) << "\" stroke=\"#f4f4f4\"/>\n";
    });
  if (lx)
    minor(x_min, x_max, [&](double x) {
      svg << "<line x1=\"" << fmt(px(x)) << "\" x2=\"" << fmt(px(x)) << "\" y1=\"" << fmt(top)
          << "\" y2=\"" << fmt(bottom) << "\" stroke=\"#f4f4f4\"/>\n";
    });
  for (const auto& [y, label] : ly ? log_ticks(lo, hi) : linear_ticks(lo, hi, 6)) {
    svg << "<line x1=\"" << fmt(left) << "\" x2=\"" << fmt(right) << "\" y1=\"" << fmt(py(y))
        << "\" y2=\"" << fmt(py(y)) << "\" stroke=\"#e6e6e6\"/>\n";
    svg << "<text x=\"" << fmt(left - 6) << "\" y=\"" << fmt(py(y) + 4)
        << "\" font-size=\"11\" text-anchor=\"end\">" << label << "</text>\n";
  }
  for (const auto& [x, label] : lx ? log_ticks(x_min, x_max) : linear_ticks(x_min, x_max, 8)) {
    svg << "<line x1=\"" << fmt(px(x)) << "\" x2=\"" << fmt(px(x)) << "\" y1=\"" << fmt(top)
        << "\" y2=\"" << fmt(bottom) << "\" stroke=\"#e6e6e6\"/>\n";
    svg << "<text x=\"" << fmt(px(x)) << "\" y=\"" << fmt(bottom + 16)
        << "\" font-size=\"11\" text-anchor=\"middle\">" << label << "</text>\n";
  }
  svg << "<rect x=\"" << fmt(left) << "\" y=\"" << fmt(top) << "\" width=\"" << fmt(right - left)
      << "\" height=\"" << fmt(bottom - top) << "\" fill=\"none\" stroke=\"#444\"/>\n";
  svg << "<text x=\"" << fmt((left + right) / 2) << "\" y=\"" << fmt(bottom + 34)
      << "\" font-size=\"12\" text-anchor=\"middle\">" << escape(panel.x_label) << "</text>\n";
  svg << "<text transform=\"translate(" << fmt(18) << "," << fmt((top + bottom) / 2)
      << ") rotate(-90)\" font-size=\"12\" text-anchor=\"middle\">" << escape(panel.y_label)
      << "</text>\n";
  if (has_reference)
    svg << "<line x1=\"" << fmt(left) << "\" x2=\"" << fmt(right) << "\" y1=\""
        << fmt(py(reference)) << "\" y2=\"" << fmt(py(reference))
        << "\" stroke=\"#888\" stroke-dasharray=\"2,3\"/>\n";

  // Data, clipped to the frame; points sorted by x so a wrapped loop draws left to right.
  svg << "<clipPath id=\"clip" << static_cast<int>(y0) << "\"><rect x=\"" << fmt(left) << "\" y=\""
      << fmt(top) << "\" width=\"" << fmt(right - left) << "\" height=\"" << fmt(bottom - top)
      << "\"/></clipPath>\n";
  // The legend: inside the frame's top right corner, or in its own column.
  const double legend_x = layout.legend_width > 0 ? right + 12 : right - 230;
  double legend_y = top + 14;
  for (const Series& s : panel.series) {
    std::vector<std::pair<double, double>> pts;
    for (const auto& [x, y] : s.points) pts.emplace_back(axis_value(x, lx), axis_value(y, ly));
    std::sort(pts.begin(), pts.end());
    const std::string dash = !s.dash_pattern.empty() ? s.dash_pattern
                             : s.dashed              ? std::string("5,3")
                                                     : std::string();
    const std::string dash_attr = dash.empty() ? "" : " stroke-dasharray=\"" + dash + "\"";
    svg << "<polyline clip-path=\"url(#clip" << static_cast<int>(y0)
        << ")\" fill=\"none\" stroke=\"" << s.colour << "\" stroke-width=\"1.3\"" << dash_attr
        << " points=\"";
    for (const auto& [x, y] : pts) svg << fmt(px(x)) << ',' << fmt(py(y)) << ' ';
    svg << "\"/>\n";
    if (s.markers)
      for (const auto& [x, y] : pts)
        svg << "<circle clip-path=\"url(#clip" << static_cast<int>(y0) << ")\" cx=\"" << fmt(px(x))
            << "\" cy=\"" << fmt(py(y)) << "\" r=\"2.5\" fill=\"" << s.colour << "\"/>\n";
    svg << "<line x1=\"" << fmt(legend_x) << "\" x2=\"" << fmt(legend_x + 25) << "\" y1=\""
        << fmt(legend_y - 4) << "\" y2=\"" << fmt(legend_y - 4) << "\" stroke=\"" << s.colour
        << "\" stroke-width=\"2\"" << dash_attr << "/>\n";
    if (s.markers)
      svg << "<circle cx=\"" << fmt(legend_x + 12.5) << "\" cy=\"" << fmt(legend_y - 4)
          << "\" r=\"2.5\" fill=\"" << s.colour << "\"/>\n";
    svg << "<text x=\"" << fmt(legend_x + 30) << "\" y=\"" << fmt(legend_y)
        << "\" font-size=\"11\">" << escape(s.label) << "</text>\n";
    legend_y += 15;
  }
}

}  // namespace

bool write_svg(const std::string& path, const std::string& title, const std::vector<Panel>& panels,
               const SvgLayout& layout) {
  std::ostringstream svg;
  const double width = layout.width;
  const double height = kTitleHeight + layout.panel_height * double(panels.size());
  svg << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << fmt(width) << "\" height=\""
      << fmt(height) << "\" viewBox=\"0 0 " << fmt(width) << ' ' << fmt(height)
      << "\" font-family=\"sans-serif\">\n";
  svg << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  svg << "<text x=\"" << fmt(width / 2) << "\" y=\"26\" font-size=\"16\" text-anchor=\"middle\">"
      << escape(title) << "</text>\n";
  for (std::size_t i = 0; i < panels.size(); ++i)
    draw_panel(svg, panels[i], kTitleHeight + layout.panel_height * double(i), layout);
  svg << "</svg>\n";
  std::ofstream out(path);
  out << svg.str();
  return static_cast<bool>(out);
}

}  // namespace stlrefine::fidelity
