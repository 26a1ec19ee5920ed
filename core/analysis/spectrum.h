// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Eigenvalues of a local subdivision matrix, grouped by Fourier frequency. The matrix
// commutes with the rotation by one sector, so the discrete Fourier transform over the n
// sectors splits it into one small block per frequency f (the centre only takes part in
// f = 0); frequencies f and n - f are complex conjugates and are reported together.

#include <Eigen/Dense>
#include <complex>
#include <vector>

#include "core/analysis/local_matrix.h"

namespace stlrefine::analysis {

//! One eigenvalue (a cluster of numerically equal ones) of the full matrix.
struct Eigenvalue {
  //! The value of the frequency-f block (its conjugate belongs to n - f).
  std::complex<double> value;
  //! 0..n/2; the eigenvectors are x_p exp(2 pi i f k / n) over sector k.
  int frequency = 0;
  //! Multiplicities in the full matrix (both f and n - f counted when 0 < f < n/2).
  int algebraic = 1;
  int geometric = 1;

  double modulus() const { return std::abs(value); }
  bool jordan() const { return geometric < algebraic; }
};

//! The block of frequency f: B_f[p][q] = sum_k A[(p, 0), (q, k)] w^(f k), w = e^(2 pi i/n),
//! with the centre as row and column 0 when f = 0 (size m + 1, else m; m = positions).
Eigen::MatrixXcd fourier_block(const LocalMatrix& a, int frequency);

//! Every eigenvalue of `a` by modulus, largest first (ties: lower frequency first).
//! Eigenvalues of one block closer than `cluster_tol` are one value (their mean, which is
//! accurate even where a Jordan block spreads the computed roots): algebraic multiplicity
//! is the cluster size, geometric multiplicity the null space of (B_f - value I).
std::vector<Eigenvalue> spectrum(const LocalMatrix& a, double cluster_tol = 1e-4);

//! Eigenvalues of a small dense matrix (curve rules), clustered the same way.
std::vector<Eigenvalue> spectrum(const Eigen::MatrixXd& a, double cluster_tol = 1e-4);

//! Right eigenvector of block f for `value` (unit length), for the characteristic map.
Eigen::VectorXcd block_eigenvector(const LocalMatrix& a, int frequency, std::complex<double> value);

//! Reif's characteristic map of a pair of eigenvectors of frequency f (Re and Im of
//! x_p w^(f k)), checked on the scheme's own refinement of that planar net: the first
//! surface ring (between the part of the refined net the rings determine and its 1/scale
//! copy) after `levels` steps must be made of positively oriented triangles (regular)
//! bounded by two simple curves (then it is injective). A pair of frequency f >= 2 wraps
//! f times around the centre and is never injective.
struct CharacteristicMapCheck {
  bool checked = false;  //!< false when the rings determine no surface ring
  bool regular = false;
  bool injective = false;
  //! Smallest triangle area of the ring over the mean one (0 or less: folded).
  double min_area_ratio = 0;
  int levels = 0;
  int inner_ring = 0, outer_ring = 0;  //!< polar rings of the checked annulus, finest level
};

CharacteristicMapCheck check_characteristic_map(const Refiner& refiner, const LocalMatrix& a,
                                                const Eigen::VectorXcd& eigenvector, int frequency,
                                                int levels);

//! What the spectrum says about smoothness at a vertex of this valence.
struct SpectralSummary {
  std::vector<Eigenvalue> values;
  //! The subdominant modulus (largest below the dominant 1) and where it sits.
  double lambda = 0;
  std::vector<int> lambda_frequencies;
  int lambda_multiplicity = 0;  //!< algebraic, summed over its frequencies
  //! Largest modulus below lambda (0 if none).
  double next = 0;
  //! The largest eigenvalue of frequency 1 (the pair that spans the characteristic map).
  std::complex<double> frequency1 = 0;
  //! 1 is simple, lambda is a real double eigenvalue of frequency 1 with two eigenvectors,
  //! every other modulus is below lambda, and the characteristic map is regular and
  //! injective: Reif's sufficient condition for a C1 (G1) limit (PU Theorem 4.1, k = 1).
  bool c1 = false;
  //! The same with lambda defective: its frequency-1 copies carry Jordan chains of equal
  //! length (two eigenvectors, algebraic multiplicity above 2), as PU's G1 butterfly keeps
  //! at valence 3. The leading terms of the expansion are then k lambda^k times the
  //! eigenvector pair, which still spans the characteristic map.
  bool c1_jordan = false;
  //! ... and every other modulus is below lambda^2, apart from a semisimple lambda^2 at
  //! frequency 0 or 2 (the quadratics |z|^2 and z^2 of the characteristic map, which Loop's
  //! own frequency-0 lambda^2 is; spec 6): the eigenvalue part of PU Theorem 4.1, k = 2.
  bool g2_eigenvalues = false;
  CharacteristicMapCheck characteristic_map;
};

//! Matrix, spectrum and checks for one valence. `map_levels` steps for the map check (0
//! skips it).
SpectralSummary summarize(const Refiner& refiner, const LocalMatrix& a, int map_levels);

}  // namespace stlrefine::analysis
