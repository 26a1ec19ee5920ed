// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Prautzsch and Umlauf's spectral modification (spec 6): selected eigenvalues of a local
// subdivision matrix A are moved by A' = A - sum (mu - target) P, where P is the Riesz
// projector onto mu's generalised eigenspace, restricted to one Fourier frequency. Unlike
// A = V diag V^-1 this stays exact for Jordan blocks (Loop and the butterfly at valence
// 3), and every other eigenvalue keeps its eigenvectors, the subdominant pair (the
// characteristic map) included (PU Lemma 5.1).

#include <complex>
#include <vector>

#include "core/analysis/local_matrix.h"
#include "core/analysis/spectrum.h"

namespace stlrefine::analysis {

//! Move the cluster `value` of the frequency-f block (with its conjugate at n - f) to a
//! value of modulus `target` (same argument).
struct EigenvalueMove {
  int frequency = 0;
  std::complex<double> value;
  double target = 0;
};

//! The lifted, real, block-circulant matrix Re(c P) over the full net, P the Riesz
//! projector (1/2 pi i) contour integral of (z - B_f)^-1 on a circle of `radius` around
//! `value` (128-point trapezoid rule; geometric convergence), B_f the frequency-f block.
//! The partner at n - f is included (factor 2 for 0 < f < n/2); a complex cluster of the
//! real blocks f = 0, n/2 needs its conjugate moved as its own entry.
Eigen::MatrixXd lifted_projector(const LocalMatrix& a, int frequency, std::complex<double> value,
                                 double radius, std::complex<double> c = 1.0);

//! Half the distance from `value` to the nearest other eigenvalue of its block (the
//! contour radius), at most 1/4 of its own modulus or 1/8 if it is 0.
double isolation_radius(const std::vector<Eigenvalue>& spectrum, int frequency,
                        std::complex<double> value);

//! The matrices that parametrise a modification linearly: A' = A - t (M - s Q) moves
//! every selected value mu to modulus s (times the fraction t; t = 1 is the full move),
//! with M = sum Re(mu P_mu) and Q = sum Re(mu / |mu| P_mu). Cached per valence by the
//! spectral schemes, so a request's parameters (kappa, ramp) cost no eigen-analysis.
struct ModificationBasis {
  Eigen::MatrixXd m;
  Eigen::MatrixXd q;
};
ModificationBasis modification_basis(const LocalMatrix& a,
                                     const std::vector<EigenvalueMove>& moves);

//! A - (M - target Q) for moves that all share one target: the modified matrix.
LocalMatrix modified_matrix(const LocalMatrix& a, const std::vector<EigenvalueMove>& moves);

}  // namespace stlrefine::analysis
