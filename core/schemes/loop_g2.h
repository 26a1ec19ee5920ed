// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <memory>
#include <vector>

#include "core/analysis/spectrum.h"
#include "core/schemes/spectral_stencil.h"

namespace stlrefine {

//! Highest valence with derived masks for loop-g2 and butterfly-g1; vertices of higher
//! valence keep the base rules (documented in README and docs/spectra.md).
inline constexpr int kSpectralMaxValence = 48;

//! Prautzsch and Umlauf's G2 rule for Loop ("Improved triangular subdivision schemes",
//! CGI 1998, section 5; spec 6): every eigenvalue mu with lambda^2 <= |mu| < lambda moves
//! below lambda^2, lambda = 3/8 + cos(2 pi/n)/4 the subdominant one, except a semisimple
//! lambda^2 at frequency 0 or 2 (the quadratics of the characteristic map, which Loop's own
//! frequency-0 eigenvalue is). Only valence 3 (1/8 and the Jordan block at 1/16) and
//! valences >= 7 (the frequencies f >= 2 with 3/8 + cos(2 pi f/n)/4 >= lambda^2) change.
MoveSelection loop_g2_rule(const std::vector<analysis::Eigenvalue>& spectrum);

//! The masks of every valence 3..kSpectralMaxValence, derived from LoopStencil's own local
//! subdivision matrices on first use (thread-safe) and immutable afterwards.
const SpectralMaskTable& loop_g2_masks();

//! Loop with Hoppe's crease rules everywhere and the G2 masks around extraordinary vertices
//! with two clean regular rings. `kappa` in (0, 1]: the moved eigenvalues go to
//! kappa lambda^2. `ramp_steps` > 0: Remark 5.3, the move grows as sqrt(step/ramp_steps)
//! (plain Loop in the first step) and is complete from step ramp_steps on.
std::unique_ptr<Split4Stencil> make_loop_g2_stencil(double kappa, int ramp_steps);

}  // namespace stlrefine
