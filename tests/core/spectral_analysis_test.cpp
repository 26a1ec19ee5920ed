// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// core/analysis against the papers: local subdivision matrices built from the production
// stencils must show Loop's lambda = 3/8 + cos(2 pi/n)/4, the modified butterfly's
// 1, 1/2, 1/2, 1/4, the original butterfly's values of spec 6, the curve rules' spectra,
// and regular, injective characteristic maps where the papers prove smoothness.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "core/analysis/polar_net.h"
#include "core/analysis/spectrum.h"
#include "core/schemes/butterfly.h"
#include "core/schemes/loop.h"
#include "core/schemes/registry.h"

namespace stlrefine::test {
namespace {

using analysis::Eigenvalue;
using analysis::LocalMatrix;
using analysis::PolarLayout;
using analysis::Refiner;

double loop_lambda(int n) {
  return 3.0 / 8.0 + std::cos(2 * std::numbers::pi / n) / 4.0;
}

// Sum of algebraic multiplicities of eigenvalues equal to `value` at `frequency`
// (-1: any frequency).
int count(const std::vector<Eigenvalue>& values, double value, int frequency = -1) {
  int c = 0;
  for (const Eigenvalue& e : values)
    if (std::abs(e.value - value) < 1e-9 && (frequency < 0 || e.frequency == frequency))
      c += e.algebraic;
  return c;
}

// --- polar net

TEST(PolarNet, LayoutAndWalkAgree) {
  for (int n : {3, 5, 8}) {
    const analysis::PolarNet net = analysis::make_polar_net(n, 4);
    EXPECT_EQ(net.mesh.check_invariants(), "");
    EXPECT_EQ(int(net.mesh.num_vertices()), (PolarLayout{n, 4}.size()));
    EXPECT_EQ(net.mesh.valence(VertexId(0)), n);
    // Spoke 0 is the centre's edge to (0, 1, 0); walking 3 rings finds the layout again.
    HalfedgeId spoke;
    for_each_outgoing(net.mesh, VertexId(0), [&](HalfedgeId h) {
      if (net.mesh.to(h) == net.ids[PolarLayout{n, 4}.index(0, 0)]) spoke = h;
    });
    const std::vector<VertexId> walked = analysis::walk_polar_net(net.mesh, spoke, 3);
    ASSERT_EQ(int(walked.size()), (PolarLayout{n, 3}.size()));
    for (std::size_t i = 0; i < walked.size(); ++i) EXPECT_EQ(walked[i], net.ids[i]) << i;
    // Four rings reach the boundary (not interior valence 6): no net.
    EXPECT_TRUE(analysis::walk_polar_net(net.mesh, spoke, 4).empty());
  }
}

TEST(PolarNet, PositionsEnumerateRingsInOrder) {
  int a, b;
  PolarLayout::lattice(0, a, b);
  EXPECT_EQ(a * 10 + b, 10);
  for (int p = 0; p < 15; ++p) {
    PolarLayout::lattice(p, a, b);
    EXPECT_EQ(PolarLayout::position(a, b), p);
    EXPECT_EQ(PolarLayout::ring_of(p), a + b);
  }
}

// --- the matrix itself

TEST(LocalMatrix, RowsSumToOneAndSymmetryFillIsExact) {
  // LSF is not linear: its matrix is the linearisation at the flat net, and its fits switch
  // their damping on the sample's conditioning, which a 1e-9 z offset can tip: 1e-8 there.
  for (const char* name : {"loop", "butterfly", "lsf"}) {
    const double tol = std::string(name) == "lsf" ? 1e-8 : 1e-13;
    const auto s = make_scheme(name);
    const Refiner refine = Refiner::of(*s);
    for (int n : {3, 4, 7}) {
      const LocalMatrix fast = analysis::local_subdivision_matrix(refine, n);
      const LocalMatrix slow =
          analysis::local_subdivision_matrix(refine, n, {fast.layout.rings, false});
      EXPECT_LT((fast.a - slow.a).cwiseAbs().maxCoeff(), tol) << name << " " << n;
      EXPECT_LT((fast.a.rowwise().sum().array() - 1).abs().maxCoeff(), tol) << name << " " << n;
    }
  }
}

TEST(LocalMatrix, RingsAreTheSmallestNetThatDeterminesASurfaceRing) {
  // Spec 6 / PU section 4: two rings for Loop, three for the butterfly.
  EXPECT_EQ(analysis::local_subdivision_matrix(Refiner::of(*make_scheme("loop")), 5).layout.rings,
            2);
  EXPECT_EQ(
      analysis::local_subdivision_matrix(Refiner::of(*make_scheme("butterfly")), 5).layout.rings,
      3);
  const ButterflyStencil original(ButterflyStencil::Extraordinary::EightPoint);
  EXPECT_EQ(analysis::local_subdivision_matrix(Refiner::of(original), 9).layout.rings, 3);
}

TEST(LocalMatrix, FourierBlocksHoldEveryEigenvalue) {
  const auto s = make_scheme("butterfly");
  const LocalMatrix a = analysis::local_subdivision_matrix(Refiner::of(*s), 5);
  Eigen::EigenSolver<Eigen::MatrixXd> direct(a.a, false);
  std::vector<double> full;
  for (auto v : direct.eigenvalues()) full.push_back(std::abs(v));
  std::vector<double> blocks;
  for (const Eigenvalue& e : analysis::spectrum(a))
    for (int i = 0; i < e.algebraic; ++i) blocks.push_back(e.modulus());
  ASSERT_EQ(full.size(), blocks.size());
  std::sort(full.rbegin(), full.rend());
  std::sort(blocks.rbegin(), blocks.rend());
  for (std::size_t i = 0; i < full.size(); ++i)
    EXPECT_NEAR(full[i], blocks[i], full[i] > 0.05 ? 1e-9 : 1e-4) << i;
}

// --- Loop (spec 1, 6)

TEST(LoopSpectrum, SubdominantIsThreeEighthsPlusCosOverFour) {
  const auto s = make_scheme("loop");
  const Refiner refine = Refiner::of(*s);
  for (int n = 3; n <= 16; ++n) {
    SCOPED_TRACE("valence " + std::to_string(n));
    const analysis::SpectralSummary sum =
        analysis::summarize(refine, analysis::local_subdivision_matrix(refine, n), 4);
    const double lambda = loop_lambda(n);
    EXPECT_NEAR(sum.lambda, lambda, 1e-12);
    EXPECT_EQ(sum.lambda_frequencies, std::vector<int>{1});
    EXPECT_EQ(sum.lambda_multiplicity, 2);
    // Loop's beta makes the frequency-0 eigenvalue exactly lambda^2 (spec 1).
    EXPECT_GE(count(sum.values, lambda * lambda, 0), 1);
    // The ring-2 block: 1/8 and 1/16 at every frequency.
    EXPECT_GE(count(sum.values, 1.0 / 8, 1), 2);
    EXPECT_GE(count(sum.values, 1.0 / 16, 1), 2);
    EXPECT_TRUE(sum.characteristic_map.regular);
    EXPECT_TRUE(sum.characteristic_map.injective);
    EXPECT_TRUE(sum.c1);
    // G2 eigenvalue condition: only n = 4, 5, 6 meet it (spec 6).
    EXPECT_EQ(sum.g2_eigenvalues, n >= 4 && n <= 6);
  }
}

TEST(LoopSpectrum, ValenceThreeHasAJordanBlockAtOneSixteenth) {
  // Spec 6: 1/16 has algebraic multiplicity 4 and geometric 3; at frequency 0 Loop's own
  // lambda^2 couples with the ring-2 block.
  const auto s = make_scheme("loop");
  const std::vector<Eigenvalue> v =
      analysis::spectrum(analysis::local_subdivision_matrix(Refiner::of(*s), 3));
  int alg = 0, geo = 0;
  for (const Eigenvalue& e : v)
    if (std::abs(e.value - 1.0 / 16) < 1e-9) alg += e.algebraic, geo += e.geometric;
  EXPECT_EQ(alg, 4);
  EXPECT_EQ(geo, 3);
  EXPECT_EQ(count(v, 1.0 / 8), 3);
  EXPECT_EQ(count(v, 0.25, 1), 2);
}

// --- butterfly (spec 2, 6)

TEST(ButterflySpectrum, ModifiedButterflyIsOneHalfHalfQuarter) {
  // Spec 2: 1, 1/2, 1/2 at frequency 1, then 1/4 (x3 for k >= 5 at frequencies 0 and 2,
  // x2 for k = 4, x1 for k = 3); everything else is at most 1/4.
  const auto s = make_scheme("butterfly");
  const Refiner refine = Refiner::of(*s);
  for (int n = 3; n <= 16; ++n) {
    if (n == 6) continue;
    SCOPED_TRACE("valence " + std::to_string(n));
    const analysis::SpectralSummary sum =
        analysis::summarize(refine, analysis::local_subdivision_matrix(refine, n), 4);
    EXPECT_NEAR(sum.lambda, 0.5, 1e-12);
    EXPECT_EQ(sum.lambda_frequencies, std::vector<int>{1});
    EXPECT_EQ(sum.lambda_multiplicity, 2);
    EXPECT_NEAR(sum.next, 0.25, 1e-9);
    EXPECT_EQ(count(sum.values, 0.25, 0), 1);
    EXPECT_EQ(count(sum.values, 0.25, 2), n >= 5 ? 2 : n == 4 ? 1 : 0);
    EXPECT_TRUE(sum.c1) << "the modified butterfly is C1 at every valence";
  }
}

TEST(ButterflySpectrum, OriginalButterflyMatchesPrautzschUmlauf) {
  // Spec 6 (w = 1/16, the 8-point stencil everywhere): valence 3 has lambda = 1/4 with
  // algebraic multiplicity 7, geometric 3; 4..7 have the frequency-1 pair subdominant;
  // from 8 on a frequency-2 pair is larger than the frequency-1 one.
  const ButterflyStencil original(ButterflyStencil::Extraordinary::EightPoint);
  const Refiner refine = Refiner::of(original);
  const auto at = [&](int n) {
    return analysis::summarize(refine, analysis::local_subdivision_matrix(refine, n), 4);
  };
  const analysis::SpectralSummary three = at(3);
  EXPECT_NEAR(three.lambda, 0.25, 1e-9);
  EXPECT_EQ(three.lambda_multiplicity, 7);
  int geo = 0;
  for (const Eigenvalue& e : three.values)
    if (std::abs(e.value - 0.25) < 1e-9) geo += e.geometric;
  EXPECT_EQ(geo, 3);
  EXPECT_FALSE(three.c1);
  const double subdominant[] = {0.46904, 0.50668, 0.5, 0.48191};
  for (int n = 4; n <= 7; ++n) {
    const analysis::SpectralSummary s = at(n);
    EXPECT_NEAR(s.lambda, subdominant[n - 4], 5e-6) << n;
    EXPECT_EQ(s.lambda_frequencies, std::vector<int>{1}) << n;
    EXPECT_TRUE(s.c1) << n;
  }
  const double largest[] = {0.46904, 0.49729, 0.50668}, frequency1[] = {0.46242, 0.44443, 0.42860};
  for (int n = 8; n <= 10; ++n) {
    const analysis::SpectralSummary s = at(n);
    EXPECT_NEAR(s.lambda, largest[n - 8], 5e-6) << n;
    EXPECT_EQ(s.lambda_frequencies, std::vector<int>{2}) << n;
    EXPECT_NEAR(s.frequency1.real(), frequency1[n - 8], 5e-6) << n;
    EXPECT_FALSE(s.c1) << n;
    // PU: the frequency-1 pair still spans a regular, injective ring ...
    EXPECT_TRUE(s.characteristic_map.injective) << n;
    // ... while the subdominant frequency-2 pair wraps twice around: not injective.
    const LocalMatrix a = analysis::local_subdivision_matrix(refine, n);
    const analysis::CharacteristicMapCheck f2 = analysis::check_characteristic_map(
        refine, a, analysis::block_eigenvector(a, 2, s.lambda), 2, 4);
    EXPECT_TRUE(f2.checked) << n;
    EXPECT_FALSE(f2.injective) << n;
  }
}

// --- curve rules (spec 1, 2, 5)

std::vector<double> curve_values(const char* scheme) {
  const auto s = make_scheme(scheme);
  std::vector<double> out;
  for (const Eigenvalue& e :
       analysis::spectrum(analysis::curve_subdivision_matrix(Refiner::of(*s))))
    for (int i = 0; i < e.algebraic; ++i) out.push_back(e.value.real());
  return out;
}

TEST(CurveSpectrum, LoopCreaseIsTheCubicBSpline) {
  const std::vector<double> want{1, 0.5, 0.25, 0.125, 0.125, 0, 0};
  const std::vector<double> got = curve_values("loop");
  ASSERT_EQ(got.size(), want.size());
  for (std::size_t i = 0; i < want.size(); ++i) EXPECT_NEAR(got[i], want[i], 1e-9) << i;
}

TEST(CurveSpectrum, FourPointRule) {
  // Dyn, Levin and Gregory's 4-point rule (w = 1/16): 1, 1/2, 1/4 (a Jordan block), 1/8,
  // -1/16, -1/16; the LSF chord-length rule is the same on uniform spacing (spec 5).
  const std::vector<double> want{1, 0.5, 0.25, 0.25, 0.125, -0.0625, -0.0625};
  for (const char* scheme : {"butterfly", "lsf"}) {
    const std::vector<double> got = curve_values(scheme);
    ASSERT_EQ(got.size(), want.size()) << scheme;
    for (std::size_t i = 0; i < want.size(); ++i) EXPECT_NEAR(got[i], want[i], 1e-9) << scheme << i;
  }
}

// --- sqrt3 double step (spec 3.3, 4): the full nets, not just the 1-ring

TEST(Sqrt3Spectrum, LabsikGreinerDoubleStepOnTheFullNet) {
  const auto s = make_scheme("sqrt3-interp");
  const Refiner refine = Refiner::of(*s);
  for (int n : {3, 4, 5, 7, 9}) {
    const analysis::SpectralSummary sum =
        analysis::summarize(refine, analysis::local_subdivision_matrix(refine, n), 3);
    EXPECT_NEAR(sum.lambda, 1.0 / 3, 1e-9) << n;
    EXPECT_EQ(sum.lambda_frequencies, std::vector<int>{1}) << n;
    EXPECT_NEAR(sum.next, 1.0 / 9, 1e-9) << n;
    EXPECT_TRUE(sum.c1) << n;
  }
}

}  // namespace
}  // namespace stlrefine::test
