// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// primitives=auto snaps each level's new vertices onto the recognised primitives before the
// next level is made from them (api/pipeline.cpp, refine's BetweenLevelsFn). Snapping only
// the last level left the faces between snapped vertices where the scheme's unsnapped
// levels put them: at 3 levels butterfly and sqrt3-interp ended 0.3-0.6x the input's
// distance from the truth on zipped cylinders and tori, with hundreds of turned faces.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <span>
#include <string>

#include "api/params.h"
#include "api/pipeline.h"
#include "core/io/stl.h"
#include "core/mesh/build_mesh.h"
#include "core/refine.h"
#include "tests/support/cad_like.h"
#include "tests/support/true_surface.h"

namespace stlrefine {
namespace {

using test::CadFamily;

struct Outcome {
  double rms_ratio = 0;    // sampled RMS distance from the truth / the input's
  std::size_t turned = 0;  // faces more than 60 degrees from the true normal
};

Outcome refine_auto(CadFamily family, std::uint64_t seed, const std::string& scheme, int levels) {
  const test::CadShape shape = test::make_cad_shape(family, {seed, 1.0});
  const Mesh input = build_mesh(shape.soup).mesh;
  const std::string stl = write_stl(input, StlFormat::Binary);
  const api::RefineRequest request = api::parse_refine_params(
      {{"scheme", scheme}, {"levels", std::to_string(levels)}, {"primitives", "auto"}}, {});
  const auto* data = reinterpret_cast<const std::uint8_t*>(stl.data());
  const api::RefinedMesh out =
      api::run_refine_to_mesh(std::span<const std::uint8_t>(data, stl.size()), request);
  Outcome o;
  o.rms_ratio = test::sampled_rms_distance(out.mesh, *shape.surface, 8) /
                test::sampled_rms_distance(input, *shape.surface, 8);
  o.turned = test::faces_off_truth(out.mesh, *shape.surface, 60);
  return o;
}

TEST(PrimitivesBetweenLevels, ThirdLevelStaysOnCylinderAndTorus) {
  for (CadFamily family : {CadFamily::CappedCylinder, CadFamily::Torus})
    for (const char* scheme : {"butterfly", "sqrt3-interp"})
      for (std::uint64_t seed : {1, 2}) {
        const Outcome o = refine_auto(family, seed, scheme, 3);
        SCOPED_TRACE(std::string(test::cad_family_name(family)) + " " + scheme + " seed " +
                     std::to_string(seed));
        std::printf("%s %s seed %d: RMS %.3f x input, %zu faces > 60 deg\n",
                    std::string(test::cad_family_name(family)).c_str(), scheme, int(seed),
                    o.rms_ratio, o.turned);
        EXPECT_LE(o.rms_ratio, 0.12);
        EXPECT_EQ(o.turned, 0u);
      }
}

}  // namespace
}  // namespace stlrefine
