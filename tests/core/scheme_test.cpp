// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include <gtest/gtest.h>

#include <algorithm>
#include <string>

#include "core/error.h"
#include "core/schemes/registry.h"

namespace stlrefine::test {
namespace {

TEST(Schemes, NamesIncludeLoopAndButterfly) {
  const auto names = scheme_names();
  EXPECT_NE(std::find(names.begin(), names.end(), "loop"), names.end());
  EXPECT_NE(std::find(names.begin(), names.end(), "butterfly"), names.end());
  for (std::string_view n : names) EXPECT_EQ(make_scheme(n)->name(), n);
}

TEST(Schemes, InterpolatingFlags) {
  EXPECT_FALSE(make_scheme("loop")->interpolating());
  EXPECT_TRUE(make_scheme("butterfly")->interpolating());
}

TEST(Schemes, UnknownNameThrowsWithField) {
  for (const char* bad : {"", "Loop", "butterfly ", "sqrt3x"}) {
    try {
      make_scheme(bad);
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::InvalidParameter);
      EXPECT_EQ(e.field(), "scheme");
    }
  }
}

TEST(Schemes, PredictFacesQuadruplesPerLevel) {
  for (const char* name : {"loop", "butterfly"}) {
    const auto s = make_scheme(name);
    EXPECT_EQ(s->predict_faces(20, 0), 20u);
    EXPECT_EQ(s->predict_faces(20, 1), 80u);
    EXPECT_EQ(s->predict_faces(20, 3), 1280u);
    EXPECT_EQ(s->predict_faces(12946, 8), 12946ull * 65536ull);
    EXPECT_EQ(s->predict_faces(1, 8), 65536u);
  }
}

}  // namespace
}  // namespace stlrefine::test
