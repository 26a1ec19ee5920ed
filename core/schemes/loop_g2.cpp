// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/loop_g2.h"

#include <cmath>

#include "core/schemes/loop.h"

namespace stlrefine {

MoveSelection loop_g2_rule(const std::vector<analysis::Eigenvalue>& spectrum) {
  constexpr double kTol = 1e-9;
  MoveSelection s;
  double lambda = 0;
  for (const analysis::Eigenvalue& e : spectrum)
    if (e.modulus() < 1 - kTol) lambda = std::max(lambda, e.modulus());
  const double l2 = lambda * lambda;
  s.scale = l2;
  for (const analysis::Eigenvalue& e : spectrum) {
    if (e.modulus() >= lambda - kTol || e.modulus() < l2 - kTol) continue;
    const bool quadratic =
        std::abs(e.value - l2) < kTol && (e.frequency == 0 || e.frequency == 2) && !e.jordan();
    if (!quadratic) s.moves.push_back({e.frequency, e.value, 0});
  }
  return s;
}

const SpectralMaskTable& loop_g2_masks() {
  static const LoopStencil base;
  static const SpectralMaskTable table(base, loop_g2_rule, kSpectralMaxValence);
  return table;
}

std::unique_ptr<Split4Stencil> make_loop_g2_stencil(double kappa, int ramp_steps) {
  return std::make_unique<SpectralStencil>(std::make_unique<LoopStencil>(), loop_g2_masks(),
                                           SpectralSchedule{kappa, 0, ramp_steps});
}

}  // namespace stlrefine
