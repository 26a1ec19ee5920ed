// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// A small hand-written SVG chart for stlrefine_spectral_bench: a grid of panels, each with
// polylines over subdivision levels on a linear or log10 y axis, a legend and ticks.

#include <string>
#include <utility>
#include <vector>

namespace stlrefine::spectral_bench {

struct Line {
  std::string label;
  std::string colour;  //!< any SVG colour
  bool dashed = false;
  std::vector<std::pair<double, double>> points;  //!< (level, value)
};

struct Chart {
  std::string title;
  std::string y_label;
  bool log_y = false;  //!< values <= 0 are left out of a log axis
  std::vector<Line> lines;
};

//! Charts in a grid of `columns` columns under a common title. \return false when the file
//! cannot be written.
bool write_svg(const std::string& path, const std::string& title, const std::vector<Chart>& charts,
               int columns);

}  // namespace stlrefine::spectral_bench
