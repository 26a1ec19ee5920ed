// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// A small hand-written SVG line plot (polylines, axes with ticks, a legend), so the
// fidelity figure is reproduced by the program that measures it, without plotting tools.

#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace stlrefine::fidelity {

struct Series {
  std::string label;
  std::string colour;  //!< any SVG colour, e.g. "#d62728"
  std::vector<std::pair<double, double>> points;
  bool dashed = false;
};

struct Panel {
  std::string title;
  std::string x_label, y_label;
  std::vector<Series> series;
  std::optional<double> reference_y;  //!< drawn as a thin grey line (the ideal value)
  std::optional<std::pair<double, double>> y_range;  //!< default: the data's range, padded
  double x_min = 0, x_max = 1;
};

//! Panels stacked vertically. \return false when the file cannot be written.
bool write_svg(const std::string& path, const std::string& title, const std::vector<Panel>& panels);

}  // namespace stlrefine::fidelity
