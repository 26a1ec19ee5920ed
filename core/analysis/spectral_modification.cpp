// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/analysis/spectral_modification.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <numbers>

namespace stlrefine::analysis {

namespace {

using cd = std::complex<double>;

// Unit complex number in the direction of mu (1 for mu = 0).
cd direction(cd mu) {
  return std::abs(mu) > 0 ? mu / std::abs(mu) : cd(1.0);
}

Eigen::MatrixXcd block_projector(const LocalMatrix& a, int f, cd value, double radius) {
  const Eigen::MatrixXcd b = fourier_block(a, f);
  const Eigen::Index size = b.rows();
  const Eigen::MatrixXcd id = Eigen::MatrixXcd::Identity(size, size);
  // P = (1/2 pi i) contour integral (zI - B)^-1 dz, z = value + r e^(i t): the trapezoid
  // rule gives (1/N) sum r e^(i t_j) (z_j I - B)^-1.
  constexpr int kNodes = 128;
  Eigen::MatrixXcd p = Eigen::MatrixXcd::Zero(size, size);
  for (int j = 0; j < kNodes; ++j) {
    const double t = 2 * std::numbers::pi * (j + 0.5) / kNodes;
    const cd step = radius * cd(std::cos(t), std::sin(t));
    p += step * Eigen::PartialPivLU<Eigen::MatrixXcd>((value + step) * id - b).inverse();
  }
  return p / double(kNodes);
}

Eigen::MatrixXd lift(const LocalMatrix& a, int f, const Eigen::MatrixXcd& p) {
  const PolarLayout& lay = a.layout;
  const int n = lay.valence, m = lay.positions();
  const int off = f == 0 ? 1 : 0;
  const double pair = (f == 0 || 2 * f == n) ? 1.0 : 2.0;
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(lay.size(), lay.size());
  // The inverse transform of a block-circulant matrix: X[(p,j),(q,k)] = (1/n) sum_f
  // X_f[p][q] w^(f (j - k)); the centre takes part in f = 0 only (its row sums over k).
  if (f == 0) {
    out(0, 0) = p(0, 0).real();
    for (int q = 0; q < m; ++q)
      for (int k = 0; k < n; ++k) out(0, lay.index(q, k)) = p(0, 1 + q).real() / n;
    for (int pp = 0; pp < m; ++pp)
      for (int j = 0; j < n; ++j) out(lay.index(pp, j), 0) = p(1 + pp, 0).real();
  }
  std::vector<cd> phase(n);
  for (int d = 0; d < n; ++d) {
    const double t = 2 * std::numbers::pi * ((f * d) % n) / n;
    phase[d] = pair / n * cd(std::cos(t), std::sin(t));
  }
  for (int pp = 0; pp < m; ++pp) {
    for (int q = 0; q < m; ++q) {
      for (int d = 0; d < n; ++d) {
        const double x = (p(off + pp, off + q) * phase[d]).real();
        for (int k = 0; k < n; ++k) out(lay.index(pp, k + d), lay.index(q, k)) = x;
      }
    }
  }
  return out;
}

}  // namespace

Eigen::MatrixXd lifted_projector(const LocalMatrix& a, int f, cd value, double radius, cd c) {
  return lift(a, f, c * block_projector(a, f, value, radius));
}

double isolation_radius(const std::vector<Eigenvalue>& spectrum, int f, cd value) {
  double nearest = std::abs(value) > 0 ? std::abs(value) : 0.5;
  for (const Eigenvalue& e : spectrum) {
    if (e.frequency != f) continue;
    const double d = std::abs(e.value - value);
    if (d > 1e-12) nearest = std::min(nearest, d);
  }
  return std::min(nearest / 2, std::abs(value) > 0 ? std::abs(value) / 4 : 0.125);
}

ModificationBasis modification_basis(const LocalMatrix& a,
                                     const std::vector<EigenvalueMove>& moves) {
  const std::vector<Eigenvalue> values = spectrum(a);
  ModificationBasis basis{Eigen::MatrixXd::Zero(a.a.rows(), a.a.cols()),
                          Eigen::MatrixXd::Zero(a.a.rows(), a.a.cols())};
  for (const EigenvalueMove& mv : moves) {
    const double r = isolation_radius(values, mv.frequency, mv.value);
    const Eigen::MatrixXcd p = block_projector(a, mv.frequency, mv.value, r);
    basis.m += lift(a, mv.frequency, mv.value * p);
    basis.q += lift(a, mv.frequency, direction(mv.value) * p);
  }
  return basis;
}

LocalMatrix modified_matrix(const LocalMatrix& a, const std::vector<EigenvalueMove>& moves) {
  const std::vector<Eigenvalue> values = spectrum(a);
  LocalMatrix out = a;
  for (const EigenvalueMove& mv : moves) {
    const double r = isolation_radius(values, mv.frequency, mv.value);
    out.a -=
        lifted_projector(a, mv.frequency, mv.value, r, mv.value - mv.target * direction(mv.value));
  }
  return out;
}

}  // namespace stlrefine::analysis
