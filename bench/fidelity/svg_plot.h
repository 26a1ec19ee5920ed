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
  std::string dash_pattern;  //!< SVG stroke-dasharray, e.g. "2,2"; overrides `dashed`
  bool markers = false;      //!< a small circle at every point (a single point is only that)
};

struct Panel {
  std::string title;
  std::string x_label, y_label;
  std::vector<Series> series;
  std::optional<double> reference_y;  //!< drawn as a thin grey line (the ideal value)
  std::optional<std::pair<double, double>> y_range;  //!< default: the data's range, padded
  double x_min = 0, x_max = 1;
  //! Logarithmic axes: every value (data, x_min/x_max, reference_y, y_range) must then be
  //! positive; ticks at the decades (and 2 and 5 times them when few decades are shown).
  bool log_x = false, log_y = false;
};

struct SvgLayout {
  double width = 900, panel_height = 330;
  //! > 0: the legend is drawn in a column of this width right of the frame, not inside it.
  double legend_width = 0;
};

//! Panels stacked vertically. \return false when the file cannot be written.
bool write_svg(const std::string& path, const std::string& title, const std::vector<Panel>& panels,
               const SvgLayout& layout = {});

}  // namespace stlrefine::fidelity
