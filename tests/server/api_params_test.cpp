// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include <gtest/gtest.h>

#include <string>

#include "api/params.h"
#include "core/error.h"

namespace stlrefine::api {
namespace {

// The Error a call throws (code, reason, field), or a failure when it does not throw.
template <class Fn>
Error error_of(Fn&& fn) {
  try {
    fn();
  } catch (const Error& e) {
    return e;
  }
  ADD_FAILURE() << "no Error thrown";
  return Error(ErrorCode::Internal, "none", "none");
}

RefineRequest refine_with(const RawParams& raw, RequestLimits limits = {}) {
  return parse_refine_params(raw, limits);
}

TEST(ApiParams, RefineDefaults) {
  const RefineRequest r = refine_with({});
  EXPECT_EQ(r.refine.scheme, "butterfly");
  EXPECT_EQ(r.refine.levels, 1);
  EXPECT_EQ(r.refine.features.crease_mode, CreaseMode::Auto);
  EXPECT_EQ(r.refine.max_faces, RequestLimits{}.max_faces);
  EXPECT_EQ(r.weld_tolerance, 0.0);
}

TEST(ApiParams, RefineParsesEveryField) {
  RequestLimits limits;
  limits.accept_threads = true;
  const RefineRequest r = refine_with({{"scheme", "loop"},
                                       {"levels", "3"},
                                       {"crease_angle", "42.5"},
                                       {"max_faces", "1000"},
                                       {"threads", "2"},
                                       {"weld_tolerance", "1e-6"}},
                                      limits);
  EXPECT_EQ(r.refine.scheme, "loop");
  EXPECT_EQ(r.refine.levels, 3);
  EXPECT_DOUBLE_EQ(r.refine.features.crease_angle_deg, 42.5);
  EXPECT_EQ(r.refine.features.crease_mode, CreaseMode::Angle);
  EXPECT_EQ(r.refine.max_faces, 1000u);
  EXPECT_EQ(r.refine.threads, 2);
  EXPECT_DOUBLE_EQ(r.weld_tolerance, 1e-6);
}

// crease_angle: "auto" or absent selects Auto detection, a number Angle mode (issue 17 item 5).
TEST(ApiParams, CreaseAngleAutoOrDegrees) {
  EXPECT_EQ(refine_with({{"crease_angle", "auto"}}).refine.features.crease_mode, CreaseMode::Auto);
  const RefineRequest angle = refine_with({{"crease_angle", "0"}});
  EXPECT_EQ(angle.refine.features.crease_mode, CreaseMode::Angle);
  EXPECT_EQ(angle.refine.features.crease_angle_deg, 0.0);
  EXPECT_EQ(parse_info_params({}).features.crease_mode, CreaseMode::Auto);
  EXPECT_EQ(parse_info_params({{"crease_angle", "auto"}}).features.crease_mode, CreaseMode::Auto);
  EXPECT_EQ(parse_info_params({{"crease_angle", "60"}}).features.crease_mode, CreaseMode::Angle);
  for (const char* bad : {"Auto", "AUTO", "auto ", "automatic"})
    EXPECT_EQ(error_of([&] {
                refine_with({{"crease_angle", bad}});
              }).field(),
              "crease_angle")
        << bad;
}

TEST(ApiParams, NumbersMustBeWholeAndFinite) {
  for (const char* bad : {"2x", "", " 2", "2 ", "+2", "0x10", "2.0", "abc", "1e3"}) {
    const Error e = error_of([&] { refine_with({{"levels", bad}}); });
    EXPECT_EQ(e.code(), ErrorCode::InvalidParameter) << bad;
    EXPECT_EQ(e.field(), "levels") << bad;
    EXPECT_EQ(e.reason(), "not_a_number") << bad;
  }
  for (const char* bad : {"nan", "NaN", "inf", "-infinity", "", "35deg", "1e400", "0x1p3", "."}) {
    const Error e = error_of([&] { refine_with({{"crease_angle", bad}}); });
    EXPECT_EQ(e.code(), ErrorCode::InvalidParameter) << bad;
    EXPECT_EQ(e.field(), "crease_angle") << bad;
  }
  EXPECT_EQ(error_of([] { refine_with({{"crease_angle", "1e400"}}); }).reason(), "out_of_range");
  EXPECT_EQ(error_of([] {
              refine_with({{"levels", "99999999999999999999"}});
            }).reason(),
            "out_of_range");
}

TEST(ApiParams, RangesComeFromCore) {
  EXPECT_EQ(error_of([] { refine_with({{"levels", "9"}}); }).field(), "levels");
  EXPECT_EQ(error_of([] { refine_with({{"levels", "-1"}}); }).field(), "levels");
  EXPECT_EQ(error_of([] { refine_with({{"crease_angle", "180.5"}}); }).field(), "crease_angle");
  EXPECT_EQ(error_of([] { refine_with({{"crease_angle", "-1"}}); }).field(), "crease_angle");
  EXPECT_EQ(error_of([] { refine_with({{"max_faces", "0"}}); }).field(), "max_faces");
  EXPECT_NO_THROW(refine_with({{"levels", "0"}, {"crease_angle", "180"}}));
}

TEST(ApiParams, UnknownSchemeNamesTheField) {
  const Error e = error_of([] { refine_with({{"scheme", "catmull-clark"}}); });
  EXPECT_EQ(e.code(), ErrorCode::InvalidParameter);
  EXPECT_EQ(e.field(), "scheme");
}

TEST(ApiParams, UnknownAndDuplicateNamesAreRejected) {
  Error e = error_of([] { refine_with({{"level", "2"}}); });
  EXPECT_EQ(e.field(), "level");
  EXPECT_EQ(e.reason(), "unknown_parameter");
  e = error_of([] { refine_with({{"levels", "1"}, {"levels", "2"}}); });
  EXPECT_EQ(e.field(), "levels");
  EXPECT_EQ(e.reason(), "duplicate_parameter");
  // threads is the CLI's: the daemon decides its own threads.
  e = error_of([] { refine_with({{"threads", "2"}}); });
  EXPECT_EQ(e.reason(), "unknown_parameter");
  // info takes no refine parameters.
  e = error_of([] { parse_info_params({{"levels", "2"}}); });
  EXPECT_EQ(e.field(), "levels");
}

TEST(ApiParams, MaxFacesMayOnlyLowerTheCap) {
  RequestLimits limits;
  limits.max_faces = 5000;
  EXPECT_EQ(refine_with({}, limits).refine.max_faces, 5000u);
  EXPECT_EQ(refine_with({{"max_faces", "10"}}, limits).refine.max_faces, 10u);
  EXPECT_EQ(refine_with({{"max_faces", "5000"}}, limits).refine.max_faces, 5000u);
  const Error e = error_of([&] { refine_with({{"max_faces", "5001"}}, limits); });
  EXPECT_EQ(e.field(), "max_faces");
  EXPECT_EQ(e.reason(), "above_server_cap");
  EXPECT_EQ(error_of([&] { refine_with({{"max_faces", "-5"}}, limits); }).reason(), "not_a_number");
}

TEST(ApiParams, DefaultMaxFacesCanSitBelowTheCap) {
  RequestLimits limits;
  limits.max_faces = 1'000'000;
  limits.default_max_faces = 1000;
  EXPECT_EQ(refine_with({}, limits).refine.max_faces, 1000u);
  EXPECT_EQ(refine_with({{"max_faces", "999999"}}, limits).refine.max_faces, 999999u);
}

TEST(ApiParams, InfoParams) {
  const InfoRequest r = parse_info_params({{"crease_angle", "20"}, {"weld_tolerance", "0.01"}});
  EXPECT_DOUBLE_EQ(r.features.crease_angle_deg, 20.0);
  EXPECT_DOUBLE_EQ(r.weld_tolerance, 0.01);
  EXPECT_EQ(error_of([] {
              parse_info_params({{"weld_tolerance", "-1"}});
            }).field(),
            "weld_tolerance");
  EXPECT_EQ(error_of([] { parse_info_params({{"crease_angle", "nan"}}); }).field(), "crease_angle");
}

TEST(ApiParams, MessagesCutLongValues) {
  const std::string huge(5000, '7');
  const Error e = error_of([&] { refine_with({{"levels", huge + "x"}}); });
  EXPECT_LT(std::string(e.what()).size(), 200u);
}

}  // namespace
}  // namespace stlrefine::api
