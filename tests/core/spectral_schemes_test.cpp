// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// loop-g2 and butterfly-g1 (spec 6): the matrices measured from the production schemes have
// exactly the designed spectrum and the base's subdominant eigenvectors, every mask sums to
// 1 and is invariant under rotation and reflection of the ring, Loop at n >= 7 is PU eq.
// (5.2), Loop at n = 3 is the spec's test vector, butterfly-g1 interpolates its input; and
// the usual scheme checks (planar stays planar, x4 faces, closed stays closed).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "core/analysis/spectral_modification.h"
#include "core/analysis/spectrum.h"
#include "core/schemes/butterfly.h"
#include "core/schemes/butterfly_g1.h"
#include "core/schemes/loop.h"
#include "core/schemes/loop_g2.h"
#include "core/schemes/registry.h"
#include "tests/core/test_util.h"
#include "tests/support/shapes.h"

namespace stlrefine::test {
namespace {

using analysis::Eigenvalue;
using analysis::LocalMatrix;
using analysis::PolarLayout;
using analysis::Refiner;

// One spectral scheme and the base it modifies.
struct Case {
  const char* name;
  SchemeOptions options;
  std::unique_ptr<Split4Stencil> (*base)();
  MoveRule rule;
  double fraction;
};

std::vector<Case> cases() {
  std::vector<Case> out;
  out.push_back({"loop-g2",
                 {},
                 [] { return std::unique_ptr<Split4Stencil>(new LoopStencil); },
                 loop_g2_rule,
                 0.5});
  out.push_back({"loop-g2", SchemeOptions{{"kappa", 0.25}},
                 [] { return std::unique_ptr<Split4Stencil>(new LoopStencil); }, loop_g2_rule,
                 0.25});
  out.push_back({"butterfly-g1",
                 {},
                 [] {
                   return std::unique_ptr<Split4Stencil>(
                       new ButterflyStencil(ButterflyStencil::Extraordinary::EightPoint));
                 },
                 butterfly_g1_rule,
                 kButterflyG1Fraction});
  return out;
}

// Eigenvalues as (frequency, value) repeated by algebraic multiplicity, sorted.
std::vector<std::pair<int, std::complex<double>>> expanded(const std::vector<Eigenvalue>& values) {
  std::vector<std::pair<int, std::complex<double>>> out;
  for (const Eigenvalue& e : values)
    for (int i = 0; i < e.algebraic; ++i) out.push_back({e.frequency, e.value});
  std::sort(out.begin(), out.end(), [](const auto& x, const auto& y) {
    if (x.first != y.first) return x.first < y.first;
    if (std::abs(x.second.real() - y.second.real()) > 1e-7)
      return x.second.real() < y.second.real();
    return x.second.imag() < y.second.imag();
  });
  return out;
}

TEST(SpectralSchemes, AreRegistered) {
  const auto names = scheme_names();
  for (const char* name : {"loop-g2", "butterfly-g1"}) {
    ASSERT_NE(std::find(names.begin(), names.end(), name), names.end()) << name;
    const auto s = make_scheme(name);
    EXPECT_EQ(s->name(), name);
    EXPECT_FALSE(s->interpolating()) << "neighbours of extraordinary vertices move";
    EXPECT_EQ(s->predict_faces(20, 3), 1280u);
  }
}

TEST(SpectralSchemes, MeasuredMatricesHaveTheDesignedSpectrum) {
  for (const Case& c : cases()) {
    const auto scheme = make_scheme(c.name, c.options);
    const auto base = c.base();
    const Refiner modified = Refiner::of(*scheme), plain = Refiner::of(*base);
    for (int n = 3; n <= 16; ++n) {
      SCOPED_TRACE(std::string(c.name) + " kappa/fraction " + std::to_string(c.fraction) +
                   " valence " + std::to_string(n));
      const LocalMatrix a = analysis::local_subdivision_matrix(plain, n);
      const LocalMatrix b = analysis::local_subdivision_matrix(modified, n, {a.layout.rings, true});
      // The design: every cluster the rule selects goes to fraction * scale, the rest stays.
      const std::vector<Eigenvalue> before = analysis::spectrum(a);
      const MoveSelection sel = c.rule(before);
      std::vector<Eigenvalue> designed = before;
      for (Eigenvalue& e : designed)
        for (const analysis::EigenvalueMove& mv : sel.moves)
          if (mv.frequency == e.frequency && std::abs(mv.value - e.value) < 1e-12)
            e.value = c.fraction * sel.scale * (e.value / std::abs(e.value));
      const auto want = expanded(designed), got = expanded(analysis::spectrum(b));
      ASSERT_EQ(got.size(), want.size());
      for (std::size_t i = 0; i < want.size(); ++i) {
        EXPECT_EQ(got[i].first, want[i].first) << i;
        EXPECT_LT(std::abs(got[i].second - want[i].second), 1e-8)
            << i << ": " << got[i].second << " vs " << want[i].second;
      }
      // Valences the rule leaves alone are bit-for-bit the base.
      if (sel.moves.empty()) {
        EXPECT_EQ((a.a - b.a).cwiseAbs().maxCoeff(), 0.0);
      }
      // Affine: every row of the measured matrix sums to 1.
      EXPECT_LT((b.a.rowwise().sum().array() - 1).abs().maxCoeff(), 1e-12);
    }
  }
}

TEST(SpectralSchemes, SubdominantEigenvectorsAreUnchanged) {
  // PU Lemma 5.1: the characteristic map is the base's.
  for (const Case& c : cases()) {
    const auto scheme = make_scheme(c.name, c.options);
    const auto base = c.base();
    const Refiner modified = Refiner::of(*scheme), plain = Refiner::of(*base);
    for (int n : {3, 7, 8, 9, 12}) {
      const LocalMatrix a = analysis::local_subdivision_matrix(plain, n);
      const LocalMatrix b = analysis::local_subdivision_matrix(modified, n, {a.layout.rings, true});
      const analysis::SpectralSummary s = analysis::summarize(plain, a, 0);
      const Eigen::VectorXcd v = analysis::block_eigenvector(a, 1, s.frequency1);
      const Eigen::VectorXcd w = analysis::block_eigenvector(b, 1, s.frequency1);
      EXPECT_NEAR(std::abs(v.dot(w)), 1.0, 1e-10) << c.name << " " << n;
      // ... and it is an eigenvector of the modified block for the same value.
      const Eigen::MatrixXcd block = analysis::fourier_block(b, 1);
      EXPECT_LT((block * v - s.frequency1 * v).norm(), 1e-12) << c.name << " " << n;
    }
  }
}

TEST(SpectralSchemes, EveryMaskSumsToOne) {
  for (const SpectralMaskTable* table : {&loop_g2_masks(), &butterfly_g1_masks()}) {
    EXPECT_EQ(table->max_valence(), kSpectralMaxValence);
    for (int n = 3; n <= kSpectralMaxValence; ++n) {
      const ValenceMasks& m = table->at(n);
      for (double fraction : {0.0, 0.5, 1.0})
        for (double t : {0.5, 1.0})
          for (const Eigen::VectorXd& row : m.rows(fraction, t))
            EXPECT_NEAR(row.sum(), 1.0, 1e-13) << n << " " << fraction << " " << t;
    }
  }
}

// The permutation of the polar layout that reflects the net across spoke 0:
// (k, a, b) -> (-k-1, b, a), or (-k, a, 0) when b = 0.
std::vector<int> reflection(const PolarLayout& lay) {
  std::vector<int> to(lay.size());
  to[0] = 0;
  for (int p = 0; p < lay.positions(); ++p) {
    int a, b;
    PolarLayout::lattice(p, a, b);
    for (int k = 0; k < lay.valence; ++k)
      to[lay.index(p, k)] =
          b == 0 ? lay.index(p, -k) : lay.index(PolarLayout::position(b, a), -k - 1);
  }
  return to;
}

TEST(SpectralSchemes, MasksAreInvariantUnderRotationAndReflection) {
  // Measured column by column (no symmetry assumed), then compared with its rotation by one
  // sector and its mirror image.
  for (const Case& c : cases()) {
    const auto scheme = make_scheme(c.name, c.options);
    const Refiner refine = Refiner::of(*scheme);
    for (int n : {3, 7, 9}) {
      const LocalMatrix a = analysis::local_subdivision_matrix(refine, n, {3, false});
      const PolarLayout& lay = a.layout;
      const std::vector<int> mirror = reflection(lay);
      auto rotate = [&](int i) {
        if (i == 0) return 0;
        return lay.index((i - 1) / n, (i - 1) % n + 1);
      };
      double rot = 0, ref = 0;
      for (int i = 0; i < lay.size(); ++i) {
        for (int j = 0; j < lay.size(); ++j) {
          rot = std::max(rot, std::abs(a.a(i, j) - a.a(rotate(i), rotate(j))));
          ref = std::max(ref, std::abs(a.a(i, j) - a.a(mirror[i], mirror[j])));
        }
      }
      EXPECT_LT(rot, 1e-12) << c.name << " " << n;
      EXPECT_LT(ref, 1e-12) << c.name << " " << n;
    }
  }
}

TEST(LoopG2, HighValencesChangeOnlyTheSpokeMaskAsInEquationFiveTwo) {
  // PU eq. (5.2): ring weight i becomes f_i - (2/n) sum_f eps_f cos(2 pi f i/n), f_0 = 3/8,
  // f_+-1 = 1/8, the others 0; eps_f = mu_f - kappa lambda^2 for the frequencies
  // 2..(n-1)/2 with mu_f = 3/8 + cos(2 pi f/n)/4 >= lambda^2. The centre keeps 3/8.
  const double kappa = 0.5;
  for (int n = 7; n <= kSpectralMaxValence; ++n) {
    SCOPED_TRACE("valence " + std::to_string(n));
    const ValenceMasks& m = loop_g2_masks().at(n);
    ASSERT_EQ(m.rings, 1);
    ASSERT_EQ(m.positions, std::vector<int>{0});  // the spoke edge point only
    const Eigen::VectorXd row = m.rows(kappa, 1.0)[0];
    const double lambda = 3.0 / 8 + std::cos(2 * std::numbers::pi / n) / 4;
    EXPECT_NEAR(row[0], 3.0 / 8, 1e-13);
    for (int i = 0; i < n; ++i) {
      double want = i == 0 ? 3.0 / 8 : (i == 1 || i == n - 1) ? 1.0 / 8 : 0.0;
      for (int f = 2; 2 * f <= n - 1; ++f) {
        const double mu = 3.0 / 8 + std::cos(2 * std::numbers::pi * f / n) / 4;
        if (mu >= lambda * lambda)
          want -=
              2.0 / n * (mu - kappa * lambda * lambda) * std::cos(2 * std::numbers::pi * f * i / n);
      }
      EXPECT_NEAR(row[1 + i], want, 1e-12) << "ring weight " << i;
    }
  }
  // Spec 6's worked example.
  const Eigen::VectorXd seven = loop_g2_masks().at(7).rows(0.5, 1.0)[0];
  const double example[] = {0.324012, 0.136346, 0.045938, -0.031790, -0.031790, 0.045938, 0.136346};
  for (int i = 0; i < 7; ++i) EXPECT_NEAR(seven[1 + i], example[i], 5e-7) << i;
}

TEST(LoopG2, ValenceThreeMatchesTheSpecTestVector) {
  // Spec 6: all moved eigenvalues set to 0 (kappa -> 0).
  const ValenceMasks& m = loop_g2_masks().at(3);
  ASSERT_EQ(m.rings, 2);
  const std::vector<Eigen::VectorXd> rows = m.rows(0.0, 1.0);
  const PolarLayout lay{3, 2};
  auto row_of = [&](int position) -> const Eigen::VectorXd& {
    const auto it = std::find(m.positions.begin(), m.positions.end(), position);
    EXPECT_NE(it, m.positions.end()) << position;
    return rows[it - m.positions.begin()];
  };
  auto expect = [&](const Eigen::VectorXd& row, double centre, const double(&ring)[3],
                    const char* what) {
    EXPECT_NEAR(row[0], centre, 1e-12) << what;
    for (int k = 0; k < 3; ++k)
      EXPECT_NEAR(row[lay.index(0, k)], ring[k], 1e-12) << what << " " << k;
    for (int q = 1; q < lay.positions(); ++q)  // every ring-2 weight drops to 0
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(row[lay.index(q, k)], 0.0, 1e-12) << what;
  };
  expect(row_of(-1), 2.0 / 5, {1.0 / 5, 1.0 / 5, 1.0 / 5}, "extraordinary vertex");
  expect(row_of(PolarLayout::position(1, 0)), 2.0 / 5, {11.0 / 30, 7.0 / 60, 7.0 / 60},
         "spoke edge");
  expect(row_of(PolarLayout::position(2, 0)), 47.0 / 80, {193.0 / 240, -47.0 / 240, -47.0 / 240},
         "neighbour vertex");
  expect(row_of(PolarLayout::position(1, 1)), 2.0 / 5, {9.0 / 20, 9.0 / 20, -3.0 / 10},
         "ring-1 edge");
  EXPECT_EQ(m.positions.size(), 4u);
}

TEST(LoopG2, UnchangedValencesAndTheRamp) {
  for (int n : {4, 5, 6}) EXPECT_TRUE(loop_g2_masks().at(n).empty()) << n;
  EXPECT_TRUE(loop_g2_masks().at(kSpectralMaxValence + 1).empty());
  // Remark 5.3: plain Loop in step 0, the full move from step ramp_steps on.
  const analysis::NetLevel net = analysis::make_net_level(9, 3, 3);
  const SchemeOptions ramp{{"ramp_steps", 6}};
  const auto ramped = make_scheme("loop-g2", ramp), full = make_scheme("loop-g2"),
             loop = make_scheme("loop");
  StepStats stats;
  auto at_step = [&](const Scheme& s, int step) {
    Level l = net.level;
    for (std::uint32_t v = 0; v < l.mesh.num_vertices(); ++v)
      l.mesh.mutable_positions()[v].z = std::sin(0.7 * v);  // any data
    l.step = step;
    const Level fine = s.refine_once(l, stats);
    return std::vector<Vec3>(fine.mesh.positions().begin(), fine.mesh.positions().end());
  };
  auto same = [](const std::vector<Vec3>& x, const std::vector<Vec3>& y) { return x == y; };
  EXPECT_TRUE(same(at_step(*ramped, 0), at_step(*loop, 0)));
  EXPECT_TRUE(same(at_step(*ramped, 6), at_step(*full, 6)));
  EXPECT_FALSE(same(at_step(*ramped, 3), at_step(*full, 3)));
  EXPECT_FALSE(same(at_step(*ramped, 3), at_step(*loop, 3)));
  EXPECT_FALSE(same(at_step(*full, 0), at_step(*loop, 0)));
}

// --- whole meshes

// A bipyramid whose equator is perturbed: a symmetric one only excites frequencies 0 and
// 1 around its apexes, which the masks leave alone.
Level closed_level(int apex_valence) {
  IndexedSoup soup = bipyramid_soup(apex_valence, 1.0);
  for (std::size_t i = 0; i < std::size_t(apex_valence); ++i)
    soup.positions[i] =
        soup.positions[i] * (1 + 0.15 * std::sin(2.1 * i)) + Vec3(0, 0, 0.1 * std::cos(i));
  return make_level(to_mesh(soup), 180);
}

TEST(ButterflyG1, InterpolatesTheInputAndChangesTheSurface) {
  for (int n : {3, 9, 12}) {
    const Level coarse = closed_level(n);
    const Level g1 = refine_levels("butterfly-g1", coarse, 3);
    for (std::uint32_t v = 0; v < coarse.mesh.num_vertices(); ++v)
      EXPECT_EQ(g1.mesh.position(VertexId(v)), coarse.mesh.position(VertexId(v))) << n << " " << v;
    // Not vacuous: from step 3 on the apexes have three clean rings and the masks apply.
    const HostScheme<Split4Stencil> original(
        "original",
        std::make_unique<ButterflyStencil>(ButterflyStencil::Extraordinary::EightPoint));
    Level plain = coarse;
    StepStats stats;
    for (int i = 0; i < 3; ++i) plain = original.refine_once(plain, stats);
    ASSERT_EQ(plain.mesh.num_vertices(), g1.mesh.num_vertices());
    double moved = 0;
    for (std::uint32_t v = 0; v < g1.mesh.num_vertices(); ++v)
      moved = std::max(moved,
                       distance(plain.mesh.position(VertexId(v)), g1.mesh.position(VertexId(v))));
    EXPECT_GT(moved, 1e-6) << n;
  }
}

TEST(ButterflyG1, FirstStepIsThePlainOriginalButterfly) {
  const Level coarse = closed_level(9);
  const HostScheme<Split4Stencil> original(
      "original", std::make_unique<ButterflyStencil>(ButterflyStencil::Extraordinary::EightPoint));
  StepStats stats;
  const Level a = original.refine_once(coarse, stats);
  const Level b = make_scheme("butterfly-g1")->refine_once(coarse, stats);
  EXPECT_TRUE(std::equal(a.mesh.positions().begin(), a.mesh.positions().end(),
                         b.mesh.positions().begin(), b.mesh.positions().end()));
}

TEST(SpectralSchemes, PlanarStaysPlanarFacesQuadrupleClosedStaysClosed) {
  for (const char* name : {"loop-g2", "butterfly-g1"}) {
    // A tilted planar polar net with a valence-9 centre and enough clean rings.
    analysis::NetLevel net = analysis::make_net_level(9, 4, 2);
    for (Vec3& p : net.level.mesh.mutable_positions()) p.z = 0.3 * p.x - 0.2 * p.y + 1;
    net.level.step = 0;
    const Level fine = refine_levels(name, net.level, 3);
    EXPECT_EQ(fine.mesh.num_faces(), net.level.mesh.num_faces() * 64) << name;
    for (const Vec3& p : fine.mesh.positions())
      EXPECT_NEAR(p.z, 0.3 * p.x - 0.2 * p.y + 1, 1e-12) << name;

    for (int n : {3, 8, 9}) {
      const Level coarse = closed_level(n);
      const Level out = refine_levels(name, coarse, 3);
      EXPECT_EQ(out.mesh.check_invariants(), "") << name << " " << n;
      for (HalfedgeId t : out.mesh.twins()) EXPECT_TRUE(t.valid()) << name << " " << n;
      const auto euler = [](const Mesh& m) {
        return long(m.num_vertices()) - long(m.num_edges()) + long(m.num_faces());
      };
      EXPECT_EQ(euler(out.mesh), euler(coarse.mesh)) << name << " " << n;
      EXPECT_EQ(out.mesh.num_faces(), coarse.mesh.num_faces() * 64) << name << " " << n;
    }
  }
}

TEST(SpectralSchemes, CarriedIrregularVerticesChangeNothing) {
  // The split4 host finds the irregular vertices once and carries them (scheme.h); a level
  // without them, and the stencil's separate vertex_points/edge_points (the adaptive
  // host's entry points), must give the same bits.
  std::vector<Level> inputs{closed_level(3), closed_level(9), closed_level(12),
                            make_level(to_mesh(cylinder_soup(12, 1.0, 2.0)), 35)};
  for (const char* name : {"loop-g2", "butterfly-g1"}) {
    const auto scheme = make_scheme(name);
    const auto& stencil = static_cast<const HostScheme<Split4Stencil>&>(*scheme).stencil();
    for (std::size_t i = 0; i < inputs.size(); ++i) {
      Level carried = inputs[i];
      StepStats stats;
      for (int step = 0; step < 4; ++step) {
        Level fresh = carried;
        fresh.irregular = {};
        const IrregularVertices found = irregular_vertices(fresh);
        if (step > 0) {
          ASSERT_TRUE(carried.irregular.valid_for(carried.mesh)) << name << " " << i;
          EXPECT_EQ(*carried.irregular.list, *found.list) << name << " " << i << " " << step;
        }
        EXPECT_FALSE(found.list->empty());
        std::vector<Vec3> separate(fresh.mesh.num_vertices() + fresh.mesh.num_edges());
        stencil.vertex_points(fresh, std::span<Vec3>(separate.data(), fresh.mesh.num_vertices()));
        stencil.edge_points(fresh, std::span<Vec3>(separate.data() + fresh.mesh.num_vertices(),
                                                   fresh.mesh.num_edges()));
        Level a = scheme->refine_once(carried, stats);
        const Level b = scheme->refine_once(fresh, stats);
        EXPECT_TRUE(std::equal(a.mesh.positions().begin(), a.mesh.positions().end(),
                               b.mesh.positions().begin(), b.mesh.positions().end()))
            << name << " " << i << " " << step;
        // Without the fold guard (which moves some edge points of the spiky bipyramids
        // since its 45 degree limit, split4_host.h) the host's points are the stencil's.
        StepStats unguarded_stats;
        const Level unguarded = split4(fresh, stencil, unguarded_stats, FoldGuard::Off);
        EXPECT_EQ(unguarded_stats.fold_fallbacks, 0u);
        EXPECT_TRUE(std::equal(separate.begin(), separate.end(), unguarded.mesh.positions().begin(),
                               unguarded.mesh.positions().end()))
            << name << " " << i << " " << step;
        // A copy has its own corner array: its list is found again, not trusted.
        const Level copy = a;
        EXPECT_FALSE(copy.irregular.valid_for(copy.mesh));
        carried = std::move(a);
      }
    }
  }
}

TEST(SpectralSchemes, NoMasksWithoutCleanRings) {
  // Two rings around a valence-9 vertex, the second on the boundary: neither scheme has
  // the regular rings its masks assume, so both are their base there.
  const analysis::NetLevel net = analysis::make_net_level(9, 1, 1);
  Level level = net.level;
  for (std::uint32_t v = 0; v < level.mesh.num_vertices(); ++v)
    level.mesh.mutable_positions()[v].z = std::cos(1.3 * v);
  StepStats stats;
  const auto same = [&](const Scheme& x, const Scheme& y) {
    const Level a = x.refine_once(level, stats), b = y.refine_once(level, stats);
    return std::equal(a.mesh.positions().begin(), a.mesh.positions().end(),
                      b.mesh.positions().begin(), b.mesh.positions().end());
  };
  EXPECT_TRUE(same(*make_scheme("loop-g2"), *make_scheme("loop")));
  const HostScheme<Split4Stencil> original(
      "original", std::make_unique<ButterflyStencil>(ButterflyStencil::Extraordinary::EightPoint));
  EXPECT_TRUE(same(*make_scheme("butterfly-g1"), original));
}

}  // namespace
}  // namespace stlrefine::test
