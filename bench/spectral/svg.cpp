// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "bench/spectral/svg.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>

namespace stlrefine::spectral_bench {

namespace {

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

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f", v);
  return buf;
}

std::string tick_label(double v, bool log_y) {
  char buf[32];
  if (log_y)
    std::snprintf(buf, sizeof buf, "1e%d", static_cast<int>(std::lround(v)));
  else
    std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

constexpr double kPanelW = 430, kPanelH = 300;
constexpr double kLeft = 62, kRight = 12, kTop = 30, kBottom = 112;

void panel(std::ostringstream& svg, const Chart& c, double ox, double oy) {
  double x0 = std::numeric_limits<double>::max(), x1 = -x0, y0 = x0, y1 = -x0;
  auto y_of = [&](double v) { return c.log_y ? std::log10(v) : v; };
  for (const Line& l : c.lines)
    for (const auto& [x, v] : l.points) {
      if (c.log_y && !(v > 0)) continue;
      if (!std::isfinite(v)) continue;
      x0 = std::min(x0, x), x1 = std::max(x1, x);
      y0 = std::min(y0, y_of(v)), y1 = std::max(y1, y_of(v));
    }
  if (x0 > x1) x0 = 0, x1 = 1, y0 = 0, y1 = 1;
  // Linear axes start at 0 and end at a multiple of a 1, 2 or 5 step (five to ten steps).
  double step = 1;
  if (c.log_y) {
    y0 = std::floor(y0), y1 = std::ceil(y1);
  } else {
    y0 = std::min(y0, 0.0);
    const double raw = (y1 - y0) / 5, decade = std::pow(10.0, std::floor(std::log10(raw)));
    step = raw <= decade       ? decade
           : raw <= 2 * decade ? 2 * decade
           : raw <= 5 * decade ? 5 * decade
                               : 10 * decade;
    y1 = y0 + std::ceil((y1 - y0) / step - 1e-9) * step;
  }
  if (y1 - y0 < 1e-12) y1 = y0 + 1;
  if (x1 - x0 < 1e-12) x1 = x0 + 1;
  const double pw = kPanelW - kLeft - kRight, ph = kPanelH - kTop - kBottom;
  auto px = [&](double x) { return ox + kLeft + (x - x0) / (x1 - x0) * pw; };
  auto py = [&](double y) { return oy + kTop + (1 - (y - y0) / (y1 - y0)) * ph; };

  svg << "<text x=\"" << num(ox + kPanelW / 2) << "\" y=\"" << num(oy + 18)
      << "\" text-anchor=\"middle\" font-size=\"13\" font-weight=\"bold\">" << escape(c.title)
      << "</text>\n";
  svg << "<rect x=\"" << num(ox + kLeft) << "\" y=\"" << num(oy + kTop) << "\" width=\"" << num(pw)
      << "\" height=\"" << num(ph) << "\" fill=\"none\" stroke=\"#444\"/>\n";
  // y ticks: every decade on a log axis, else five steps.
  const int steps = static_cast<int>(std::lround((y1 - y0) / step));
  const int every = std::max(1, steps / 8);
  for (int i = 0; i <= steps; i += every) {
    const double y = y0 + (y1 - y0) * i / steps;
    svg << "<line x1=\"" << num(ox + kLeft) << "\" x2=\"" << num(ox + kLeft + pw) << "\" y1=\""
        << num(py(y)) << "\" y2=\"" << num(py(y)) << "\" stroke=\"#ddd\"/>\n";
    svg << "<text x=\"" << num(ox + kLeft - 4) << "\" y=\"" << num(py(y) + 4)
        << "\" text-anchor=\"end\" font-size=\"10\">" << tick_label(y, c.log_y) << "</text>\n";
  }
  for (int x = static_cast<int>(std::ceil(x0)); x <= x1; ++x)
    svg << "<text x=\"" << num(px(x)) << "\" y=\"" << num(oy + kTop + ph + 13)
        << "\" text-anchor=\"middle\" font-size=\"10\">" << x << "</text>\n";
  svg << "<text x=\"" << num(ox + kLeft + pw / 2) << "\" y=\"" << num(oy + kTop + ph + 27)
      << "\" text-anchor=\"middle\" font-size=\"10\">level</text>\n";
  svg << "<text transform=\"translate(" << num(ox + 12) << "," << num(oy + kTop + ph / 2)
      << ") rotate(-90)\" text-anchor=\"middle\" font-size=\"10\">" << escape(c.y_label)
      << "</text>\n";

  int row = 0;
  for (const Line& l : c.lines) {
    std::string pts;
    for (const auto& [x, v] : l.points) {
      if ((c.log_y && !(v > 0)) || !std::isfinite(v)) continue;
      pts += num(px(x)) + "," + num(py(y_of(v))) + " ";
      svg << "<circle cx=\"" << num(px(x)) << "\" cy=\"" << num(py(y_of(v)))
          << "\" r=\"2.2\" fill=\"" << l.colour << "\"/>\n";
    }
    svg << "<polyline fill=\"none\" stroke=\"" << l.colour << "\" stroke-width=\"1.6\""
        << (l.dashed ? " stroke-dasharray=\"5,3\"" : "") << " points=\"" << pts << "\"/>\n";
    const double lx = ox + kLeft + (row % 2) * pw / 2, ly = oy + kTop + ph + 44 + (row / 2) * 14;
    svg << "<line x1=\"" << num(lx) << "\" x2=\"" << num(lx + 18) << "\" y1=\"" << num(ly - 4)
        << "\" y2=\"" << num(ly - 4) << "\" stroke=\"" << l.colour << "\" stroke-width=\"1.6\""
        << (l.dashed ? " stroke-dasharray=\"5,3\"" : "") << "/>\n";
    svg << "<text x=\"" << num(lx + 22) << "\" y=\"" << num(ly) << "\" font-size=\"10\">"
        << escape(l.label) << "</text>\n";
    ++row;
  }
}

}  // namespace

bool write_svg(const std::string& path, const std::string& title, const std::vector<Chart>& charts,
               int columns) {
  columns = std::max(1, columns);
  const int rows = (static_cast<int>(charts.size()) + columns - 1) / columns;
  const double w = columns * kPanelW, h = 34 + rows * kPanelH;
  std::ostringstream svg;
  svg << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << num(w) << "\" height=\"" << num(h)
      << "\" viewBox=\"0 0 " << num(w) << " " << num(h)
      << "\" font-family=\"sans-serif\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  svg << "<text x=\"" << num(w / 2) << "\" y=\"22\" text-anchor=\"middle\" font-size=\"15\">"
      << escape(title) << "</text>\n";
  for (std::size_t i = 0; i < charts.size(); ++i)
    panel(svg, charts[i], (i % columns) * kPanelW, 34 + (i / columns) * kPanelH);
  svg << "</svg>\n";
  std::ofstream out(path);
  out << svg.str();
  return static_cast<bool>(out);
}

}  // namespace stlrefine::spectral_bench
