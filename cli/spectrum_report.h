// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Plain-text and Markdown renderings of the spectral analysis: what `stlrefine spectrum`
// prints and what docs/spectra.md is generated from (so the two cannot disagree).

#include <string>
#include <string_view>
#include <vector>

#include "core/analysis/spectrum.h"

namespace stlrefine::analysis {

//! One valence analysed: the matrix and everything summarize() says about it.
struct ValenceReport {
  LocalMatrix matrix;
  SpectralSummary summary;
};

//! The default number of steps for the characteristic-map check: 4 (1-to-4), 3 (sqrt3).
int default_map_levels(const Refiner& refiner);

ValenceReport analyse_valence(const Refiner& refiner, int valence);

//! One eigenvalue (cluster) per line with modulus, frequency and multiplicities, then the
//! subdominant eigenvalue, the characteristic map and the smoothness conditions.
std::string format_lines(std::string_view title, const ValenceReport& report);

//! A Markdown table, one row per valence, with the `count` leading eigenvalues.
std::string format_table(const std::vector<ValenceReport>& reports, int count);

//! The curve rule's 1-D spectrum on one line.
std::string format_curve(std::string_view title, const std::vector<Eigenvalue>& values);

//! A number as the reports print it: 6 decimals, "0" below 5e-7, "a+bi" when complex.
std::string format_value(std::complex<double> value);

//! The whole of docs/spectra.md: every scheme over valences 3..16, the bases of the
//! spectral schemes, the curve rules and the masks loop-g2 and butterfly-g1 change.
std::string spectra_markdown();

}  // namespace stlrefine::analysis
