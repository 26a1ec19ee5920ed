// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <memory>
#include <vector>

#include "core/analysis/spectrum.h"
#include "core/schemes/spectral_stencil.h"

namespace stlrefine {

//! Prautzsch and Umlauf's G1 rule for the butterfly (CGI 1998, section 6; spec 6), applied
//! to Dyn, Levin and Gregory's original butterfly (w = 1/16, the 8-point stencil at every
//! vertex): every eigenvalue of modulus >= mu, mu the largest eigenvalue of frequency 1,
//! other than the dominant 1 and mu itself moves to mu/2, so the frequency-1 pair (a
//! regular, injective characteristic map) is subdominant. Changes valence 3 (the
//! frequency-0 Jordan block at 1/4) and valences >= 8 (frequencies >= 2 above mu).
MoveSelection butterfly_g1_rule(const std::vector<analysis::Eigenvalue>& spectrum);

//! The moved eigenvalues go to this fraction of mu (spec 6's example target mu/2).
inline constexpr double kButterflyG1Fraction = 0.5;

//! The masks of every valence 3..kSpectralMaxValence (loop_g2.h), derived on first use.
const SpectralMaskTable& butterfly_g1_masks();

//! The original butterfly with crease rules (ButterflyStencil::Extraordinary::EightPoint)
//! everywhere, plain in the first step (Remark 6.1: every input vertex is interpolated),
//! the G1 masks around extraordinary vertices with three clean regular rings afterwards.
std::unique_ptr<Split4Stencil> make_butterfly_g1_stencil();

}  // namespace stlrefine
