// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/butterfly_g1.h"

#include <cmath>

#include "core/schemes/butterfly.h"
#include "core/schemes/loop_g2.h"

namespace stlrefine {

MoveSelection butterfly_g1_rule(const std::vector<analysis::Eigenvalue>& spectrum) {
  constexpr double kTol = 1e-9;
  MoveSelection s;
  const analysis::Eigenvalue* lead = nullptr;  // the frequency-1 pair
  for (const analysis::Eigenvalue& e : spectrum)
    if (e.frequency == 1 && (!lead || e.modulus() > lead->modulus() + kTol)) lead = &e;
  if (!lead) return s;
  s.scale = lead->modulus();
  for (const analysis::Eigenvalue& e : spectrum) {
    if (&e == lead || e.modulus() < s.scale - kTol) continue;
    if (e.frequency == 0 && std::abs(e.value - 1.0) < kTol && e.algebraic == 1) continue;
    s.moves.push_back({e.frequency, e.value, 0});
  }
  return s;
}

const SpectralMaskTable& butterfly_g1_masks() {
  static const ButterflyStencil base(ButterflyStencil::Extraordinary::EightPoint);
  static const SpectralMaskTable table(base, butterfly_g1_rule, kSpectralMaxValence);
  return table;
}

std::unique_ptr<Split4Stencil> make_butterfly_g1_stencil() {
  return std::make_unique<SpectralStencil>(
      std::make_unique<ButterflyStencil>(ButterflyStencil::Extraordinary::EightPoint),
      butterfly_g1_masks(), SpectralSchedule{kButterflyG1Fraction, 1, 0});
}

}  // namespace stlrefine
