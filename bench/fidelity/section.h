// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// The paper's section-curve test (Figs. 8 and 9): cut the refined cylinder with a plane,
// parameterise the section polyline by chord length and look at how smoothly its
// derivative varies. A horizontal plane through the side of the cylinder must give a
// circle; undulation shows up as curvature that swings around 1/r and as a tangent that
// leans away from the circle's.

#include <cstddef>
#include <vector>

#include "core/mesh/mesh.h"

namespace stlrefine::fidelity {

struct SectionCurve {
  std::vector<Vec3> points;
  bool closed = false;
};

//! Intersects every face with the plane z = z0 and chains the pieces by shared edges.
//! A vertex exactly on the plane counts as above it.
std::vector<SectionCurve> cut_horizontal(const Mesh& mesh, double z0);

//! One point of the plot: a section vertex (curvature) or segment midpoint (tangent).
struct SectionSample {
  double polar_deg = 0;  //!< azimuth around the axis, [0, 360)
  double value = 0;
};

//! The undulation of a closed section that should be the circle of radius r around the
//! z axis. The paper differentiates the chord-length parameterised section once (equation
//! (4): the tangent) and looks at how smoothly that derivative varies. Here:
//! - the tangent deviation: each segment's angle to the true circle's tangent at the
//!   segment's midpoint (0 for every polygon inscribed in the circle, however uneven);
//! - the relative curvature kappa r (1 on the circle), the tangent angle's derivative by arc
//!   length over a window of `window` (the tangent angle interpolated linearly between
//!   segment midpoints, so vertices entering the window do not make it jump). A window of a
//!   few segments keeps the undulation and drops the facet-level noise a plane passing close
//!   to a mesh vertex makes.
struct SectionStats {
  std::size_t curves = 0;  //!< 1 when the cut is a single closed loop, as it should be
  std::size_t points = 0;
  double length = 0;
  double window = 0;
  double radius_max_dev = 0;  //!< max | |p_xy| - r |
  //! Tangent deviation, degrees: length-weighted RMS and max.
  double tangent_rms_deg = 0, tangent_max_deg = 0;
  //! |kappa r - 1| over evenly spaced arc-length samples: RMS and max.
  double curvature_rms = 0, curvature_max = 0;
  //! Total variation of kappa r around the loop (the undulation: 0 on a circle).
  double curvature_variation = 0;
  //! Sum of |turning angles| / 2 pi: 1 for a convex loop, more where it wiggles inwards.
  double absolute_turning = 0;
  std::vector<SectionSample> curvature;  //!< kappa r at evenly spaced arc lengths
  std::vector<SectionSample> tangent;    //!< signed tangent deviation per segment, degrees
  //! The same, length-weighted average over `window` of arc length: the facet-level
  //! zig-zag of a section through long thin triangles averages out, undulation stays.
  std::vector<SectionSample> tangent_smoothed;
  double tangent_smoothed_max_deg = 0;
};

//! Analyses the longest closed curve of `curves` (empty stats when there is none).
//! \param window arc length of the curvature window; \param samples curvature samples.
SectionStats analyse_section(const std::vector<SectionCurve>& curves, double r, double window,
                             std::size_t samples = 720);

}  // namespace stlrefine::fidelity
