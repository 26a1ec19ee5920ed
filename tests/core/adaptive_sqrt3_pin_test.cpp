// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// Pins the adaptive sqrt3 output bit for bit (positions, corners, sharp edges, face levels,
// counters) on a few meshes and criteria, so that a rewrite of the hierarchy (issue 18
// item 4: typed handles, files split) is seen to change nothing. A deliberate change of
// behaviour updates the digests here, in the same commit, and says why. The first seven run
// without the fold guard: they are the digests of the hierarchy before it had one. The digests are
// those of the Release build on x86-64 with GCC (floating-point contraction may differ
// elsewhere).
#include <gtest/gtest.h>

#include <bit>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "core/refine.h"
#include "core/schemes/adaptive_sqrt3.h"
#include "tests/core/reference_cases.h"
#include "tests/support/cad_like.h"
#include "tests/support/mesh_queries.h"
#include "tests/support/shapes.h"

namespace stlrefine::test {
namespace {

// FNV-1a over 64-bit words: any change of a bit of the output changes it.
class Digest {
 public:
  void add(std::uint64_t x) {
    for (int i = 0; i < 8; ++i) {
      h_ ^= (x >> (8 * i)) & 0xff;
      h_ *= 0x100000001b3ull;
    }
  }
  void add(double x) { add(std::bit_cast<std::uint64_t>(x)); }
  std::uint64_t value() const { return h_; }

 private:
  std::uint64_t h_ = 0xcbf29ce484222325ull;
};

// The digest of one adaptive run; `refined` gets how many triangles it refined.
std::uint64_t digest(const Level& coarse, const char* scheme, const Sqrt3AdaptiveCriteria& c,
                     std::size_t& refined) {
  const auto s = make_scheme(scheme);
  AdaptiveSqrt3 adaptive(coarse, *adaptive_sqrt3_scheme(*s), c);
  adaptive.run(1u << 24);
  std::vector<std::uint8_t> face_level;
  const Level out = adaptive.result(&face_level);
  const Mesh& m = out.mesh;
  Digest d;
  d.add(std::uint64_t(m.num_vertices()));
  d.add(std::uint64_t(m.num_faces()));
  for (const Vec3& p : m.positions()) {
    d.add(p.x);
    d.add(p.y);
    d.add(p.z);
  }
  for (std::uint32_t h = 0; h < m.num_halfedges(); ++h) {
    d.add(std::uint64_t(m.from(HalfedgeId(h)).idx));
    d.add(std::uint64_t(out.features.is_sharp(m.edge(HalfedgeId(h)))));
  }
  for (std::uint8_t l : face_level) d.add(std::uint64_t(l));
  for (double a : out.alpha) d.add(a);
  const Sqrt3AdaptiveStats& st = adaptive.stats();
  refined = st.refined_by_criterion + st.refined_by_closure;
  d.add(std::uint64_t(st.refined_by_criterion));
  d.add(std::uint64_t(st.refined_by_closure));
  d.add(std::uint64_t(st.levels));
  d.add(std::uint64_t(st.over_criterion_at_cap));
  return d.value();
}

Level cad_level(CadFamily family, std::uint64_t seed) {
  return make_level(to_mesh(make_cad_shape(family, {seed, 1.5}).soup), 35);
}

struct Pin {
  const char* name;
  const char* scheme;
  Level (*level)();
  Sqrt3AdaptiveCriteria criteria;
  std::uint64_t digest;
};

TEST(AdaptiveSqrt3Pin, OutputIsBitForBitThePinnedOne) {
  const std::vector<Pin> pins = {
      {"JitteredIcosphere interp",
       "sqrt3-interp",
       [] { return make_level(to_mesh(jittered(icosphere_soup(1, 10.0), 0.5)), 180); },
       {15, 0.02, 4, Sqrt3Closure::Stencil, FoldGuard::Off},
       0xb9822ca184df5c74ull},
      {"Torus unified tol",
       "sqrt3-unified",
       [] { return make_level(to_mesh(torus_soup(12, 8, 20.0, 6.0)), 180); },
       {0, 0.05, 5, Sqrt3Closure::Stencil, FoldGuard::Off},
       0x3c50a63a76014914ull},
      {"Cylinder kobbelt angle",
       "sqrt3",
       [] { return make_level(to_mesh(cylinder_soup(12, 10.0, 20.0)), 35); },
       {10, 0, 4, Sqrt3Closure::Stencil, FoldGuard::Off},
       0x2ba8545d7fe23883ull},
      {"BumpyOpenGrid edge closure",
       "sqrt3-interp",
       [] { return make_level(to_mesh(bumpy_grid_soup(8, 0.1)), 180); },
       {10, 0, 5, Sqrt3Closure::EdgeNeighbours, FoldGuard::Off},
       0xbac9d0b3121b6ab5ull},
      {"TaggedPolyline interp",
       "sqrt3-interp",
       [] { return tagged_polyline_level(true); },
       {10, 0.01, 5, Sqrt3Closure::Stencil, FoldGuard::Off},
       0x317727e28709a9aaull},
      {"CAD capped cylinder interp",
       "sqrt3-interp",
       [] { return cad_level(CadFamily::CappedCylinder, 3); },
       {0, 0.05, 4, Sqrt3Closure::Stencil, FoldGuard::Off},
       0x017d96168a84b471ull},
      {"CAD blob kobbelt",
       "sqrt3",
       [] { return cad_level(CadFamily::Blob, 5); },
       {0, 0.05, 4, Sqrt3Closure::Stencil, FoldGuard::Off},
       0x12b5aa42303fea8eull},
      // With the fold guard (the default): it keeps flips and moves face points on these.
      {"CAD capped cylinder interp guarded",
       "sqrt3-interp",
       [] { return cad_level(CadFamily::CappedCylinder, 3); },
       {0, 0.05, 4},
       0x777220b7f5443736ull},
      {"CAD blob kobbelt guarded",
       "sqrt3",
       [] { return cad_level(CadFamily::Blob, 5); },
       {0, 0.05, 4},
       0x64d49388e165b58aull},
  };
  for (const Pin& p : pins) {
    SCOPED_TRACE(p.name);
    std::size_t refined = 0;
    const std::uint64_t got = digest(p.level(), p.scheme, p.criteria, refined);
    EXPECT_GT(refined, 0u);  // a case that refines nothing pins nothing
#if defined(__clang__)
    // The guarded digests are GCC's: the sanitizer build (clang 14) gives other digests on
    // both guarded cases and the pinned ones on every unguarded case. The guard decides by
    // comparing angles with its limit, so a last-bit difference flips a decision; valgrind
    // finds no uninitialised read in the GCC build. Not pinned down further: the Release
    // suite (GCC) pins them.
    if (p.criteria.guard != FoldGuard::Off) continue;
#endif
    EXPECT_EQ(got, p.digest) << std::hex << "got 0x" << got;
  }
}

}  // namespace
}  // namespace stlrefine::test
