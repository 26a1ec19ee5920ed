// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// Issue 19 item 6: the same parameter names on every route. Slicing after a refinement
// takes /v1/slice's names (layer_height, heights, z_min, z_max, max_layers, slice_format);
// the old names (`slice` on /v1/refine, `format` on /v1/slice) still work, are marked
// deprecated in the OpenAPI document, conflict with their replacement, and errors quote the
// name the caller used.

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <string>

#include "api/param_table.h"
#include "api/params.h"
#include "api/pipeline.h"
#include "core/error.h"
#include "server/daemon.h"
#include "test_stl.h"

namespace stlrefine::test {
namespace {

// The field of the Error a call throws ("" when it does not throw).
template <class F>
std::string field_of(F&& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.field();
  }
  return {};
}

TEST(ParamNames, RefineSlicesWithTheSliceRouteNames) {
  const api::RefineRequest r = api::parse_refine_params(
      {{"levels", "1"}, {"layer_height", "0.25"}, {"z_min", "0.1"}, {"slice_format", "svg"}}, {});
  ASSERT_TRUE(r.slice);
  EXPECT_EQ(r.slice->params.layer_height, 0.25);
  EXPECT_EQ(r.slice->params.z_min, 0.1);
  EXPECT_EQ(r.slice->format, slicer::SliceFormat::Svg);
  EXPECT_EQ(r.slice->layer_height_name, "layer_height");

  const api::RefineRequest h = api::parse_refine_params({{"heights", "0.5,1"}}, {});
  ASSERT_TRUE(h.slice);
  EXPECT_EQ(h.slice->params.heights, (std::vector<double>{0.5, 1}));

  const api::RefineRequest old = api::parse_refine_params({{"slice", "0.25"}}, {});
  ASSERT_TRUE(old.slice);
  EXPECT_EQ(old.slice->params.layer_height, 0.25);
  EXPECT_EQ(old.slice->layer_height_name, "slice");

  EXPECT_FALSE(api::parse_refine_params({{"levels", "1"}}, {}).slice);
}

TEST(ParamNames, TheSliceRouteTakesSliceFormat) {
  EXPECT_EQ(api::parse_slice_params({{"slice_format", "cli"}}, {}).slice.format,
            slicer::SliceFormat::CliAscii);
  EXPECT_EQ(api::parse_slice_params({{"format", "cli"}}, {}).slice.format,
            slicer::SliceFormat::CliAscii);
}

TEST(ParamNames, ErrorsQuoteTheNameTheCallerUsed) {
  EXPECT_EQ(field_of([] {
              api::parse_refine_params({{"layer_height", "-1"}}, {});
            }),
            "layer_height");
  EXPECT_EQ(field_of([] { api::parse_refine_params({{"slice", "-1"}}, {}); }), "slice");
  EXPECT_EQ(field_of([] { api::parse_refine_params({{"slice", "abc"}}, {}); }), "slice");
  EXPECT_EQ(field_of([] {
              api::parse_slice_params({{"slice_format", "pdf"}}, {});
            }),
            "slice_format");
  EXPECT_EQ(field_of([] { api::parse_slice_params({{"format", "pdf"}}, {}); }), "format");
  EXPECT_EQ(field_of([] {
              api::parse_refine_params({{"layer_height", "1"}, {"slice_format", "pdf"}}, {});
            }),
            "slice_format");
  // A slicing modifier alone on /v1/refine names itself and what it needs.
  try {
    api::parse_refine_params({{"z_max", "3"}}, {});
    ADD_FAILURE() << "z_max alone was accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.field(), "z_max");
    EXPECT_EQ(e.reason(), "missing_parameter");
    EXPECT_NE(std::string(e.what()).find("layer_height"), std::string::npos) << e.what();
  }
  EXPECT_EQ(field_of([] {
              api::parse_refine_params({{"slice_format", "svg"}}, {});
            }),
            "slice_format");
}

TEST(ParamNames, AnOldNameBesideItsReplacementIsAConflict) {
  try {
    api::parse_refine_params({{"slice", "0.5"}, {"layer_height", "0.5"}}, {});
    ADD_FAILURE() << "slice and layer_height together were accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::InvalidParameter);
    EXPECT_EQ(e.field(), "slice");
    EXPECT_EQ(e.reason(), "conflicting_parameters");
  }
  EXPECT_EQ(field_of([] {
              api::parse_slice_params({{"format", "svg"}, {"slice_format", "svg"}}, {});
            }),
            "format");
}

// Found after the parameters are read (no layer fits the part): still the caller's name.
TEST(ParamNames, ALayerHeightTallerThanThePartIsNamedAsGiven) {
  const std::string stl = binary_stl(octahedron_triangles());  // 2 units tall
  const std::span<const std::uint8_t> bytes(reinterpret_cast<const std::uint8_t*>(stl.data()),
                                            stl.size());
  for (const char* name : {"layer_height", "slice"}) {
    const api::RefineRequest r =
        api::parse_refine_params({{"levels", "0"}, {name, "50"}, {"units", "mm"}}, {});
    try {
      api::run_refine(bytes, r);
      ADD_FAILURE() << name << ": a slice with no layer succeeded";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::NothingToMake) << e.what();
      EXPECT_EQ(e.field(), name);
    }
  }
}

TEST(ParamNames, TheOpenApiDocumentMarksTheOldNamesDeprecated) {
  const nlohmann::json doc = nlohmann::json::parse(server::openapi_document());
  const auto param = [&](const char* path, const char* name) {
    for (const nlohmann::json& p : doc["paths"][path]["post"]["parameters"])
      if (p["name"] == name) return p;
    return nlohmann::json();
  };
  for (const char* path : {"/v1/refine", "/v1/jobs"}) {
    EXPECT_EQ(param(path, "slice").value("deprecated", false), true) << path;
    EXPECT_FALSE(param(path, "layer_height").is_null()) << path;
    EXPECT_EQ(param(path, "layer_height").value("deprecated", false), false) << path;
    EXPECT_FALSE(param(path, "heights").is_null()) << path;
    EXPECT_FALSE(param(path, "slice_format").is_null()) << path;
  }
  EXPECT_EQ(param("/v1/slice", "format").value("deprecated", false), true);
  EXPECT_EQ(param("/v1/slice", "slice_format").value("deprecated", false), false);
  EXPECT_EQ(api::replaced_by(api::RequestKind::Refine, "slice"), "layer_height");
  EXPECT_EQ(api::replaced_by(api::RequestKind::Slice, "format"), "slice_format");
  EXPECT_TRUE(api::replaced_by(api::RequestKind::Slice, "layer_height").empty());
}

}  // namespace
}  // namespace stlrefine::test
