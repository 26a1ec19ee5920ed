// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// The parameter table (api/param_table.h) reaches all three of its users: every row is an
// option in the CLI's help, is accepted by the query parser, and is in the OpenAPI document
// of every route that takes it; and every option a scheme's registry row names has a row.

#include "api/param_table.h"

#include <gtest/gtest.h>

#include <cmath>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "api/params.h"
#include "core/error.h"
#include "core/schemes/registry.h"
#include "server/daemon.h"
#include "subprocess.h"

namespace stlrefine::test {
namespace {

using namespace std::chrono_literals;
using api::ParamRow;
using api::RequestKind;

struct Kind {
  RequestKind kind;
  const char* subcommand;
  std::vector<std::string> paths;  // of the daemon
};

const std::vector<Kind>& kinds() {
  static const std::vector<Kind> k = {
      {RequestKind::Refine, "refine", {"/v1/refine", "/v1/jobs"}},
      {RequestKind::Slice, "slice", {"/v1/slice"}},
      {RequestKind::Info, "info", {"/v1/info"}},
  };
  return k;
}

TEST(ParamTable, EveryRowIsAnOptionInTheCliHelp) {
  for (const Kind& k : kinds()) {
    const ProcessResult r = run_process({STLREFINE_CLI, k.subcommand, "--help"}, 60s);
    ASSERT_EQ(r.exit_code, 0) << k.subcommand;
    for (const ParamRow& row : api::param_table()) {
      if (!row.takes(k.kind)) continue;
      if (row.http_only) {  // the CLI has its own --report FILE
        EXPECT_EQ(row.name, "report");
        continue;
      }
      // "--slice TEXT", not the prefix of "--slice-format".
      EXPECT_NE(r.out.find(api::cli_option(row.name) + " "), std::string::npos)
          << k.subcommand << " " << row.name;
      // The help is the row's (the scheme list is added to `scheme`'s).
      if (row.name != "scheme") {
        EXPECT_NE(r.out.find(std::string(row.help.substr(0, 40))), std::string::npos)
            << k.subcommand << " " << row.name;
      }
    }
  }
}

TEST(ParamTable, EveryRowIsAcceptedByTheQueryParser) {
  api::RequestLimits cli;
  cli.accept_threads = true;
  const api::RequestLimits daemon;
  for (const ParamRow& row : api::param_table()) {
    ASSERT_FALSE(row.example.empty()) << row.name;
    const std::string name(row.name), value(row.example);
    if (row.takes(RequestKind::Refine)) {
      // The slicing modifiers need a layer height; every other row accepts it beside itself
      // (`slice`, the old name of `layer_height`, is accepted in place of it).
      api::RawParams raw = {{name, value}};
      if (name != "slice" && name != "layer_height" && name != "heights")
        raw.emplace_back("layer_height", "0.5");
      if (row.http_only) {
        EXPECT_THROW(api::parse_refine_params(raw, cli), Error) << name;
      } else {
        EXPECT_NO_THROW(api::parse_refine_params(raw, cli)) << name;
      }
      if (row.cli_only) {
        EXPECT_THROW(api::parse_refine_params(raw, daemon), Error) << name;
      } else {
        EXPECT_NO_THROW(api::parse_refine_params(raw, daemon)) << name;
      }
    }
    if (row.takes(RequestKind::Slice)) {
      if (row.http_only) {
        EXPECT_THROW(api::parse_slice_params({{name, value}}, cli), Error) << name;
      } else {
        EXPECT_NO_THROW(api::parse_slice_params({{name, value}}, cli)) << name;
      }
      if (!row.cli_only) {
        EXPECT_NO_THROW(api::parse_slice_params({{name, value}}, daemon)) << name;
      }
    }
    if (row.takes(RequestKind::Info)) {
      EXPECT_NO_THROW(api::parse_info_params({{name, value}})) << name;
    }
    // A kind that does not take it refuses it by name.
    for (const Kind& k : kinds()) {
      if (row.takes(k.kind)) continue;
      try {
        if (k.kind == RequestKind::Refine) api::parse_refine_params({{name, value}}, cli);
        if (k.kind == RequestKind::Slice) api::parse_slice_params({{name, value}}, cli);
        if (k.kind == RequestKind::Info) api::parse_info_params({{name, value}});
        ADD_FAILURE() << k.subcommand << " accepted " << name;
      } catch (const Error& e) {
        EXPECT_EQ(e.reason(), "unknown_parameter") << k.subcommand << " " << name;
      }
    }
  }
}

TEST(ParamTable, EveryRowIsInTheOpenApiDocument) {
  const nlohmann::json doc = nlohmann::json::parse(server::openapi_document());
  for (const Kind& k : kinds()) {
    for (const std::string& path : k.paths) {
      const nlohmann::json& params = doc["paths"][path]["post"]["parameters"];
      for (const ParamRow& row : api::param_table()) {
        const nlohmann::json* found = nullptr;
        for (const nlohmann::json& p : params)
          if (p["name"] == row.name) found = &p;
        if (!row.takes(k.kind) || row.cli_only) {
          EXPECT_EQ(found, nullptr) << path << " " << row.name;
          continue;
        }
        ASSERT_NE(found, nullptr) << path << " " << row.name;
        EXPECT_EQ((*found)["description"], row.description) << path << " " << row.name;
        EXPECT_EQ((*found)["schema"]["type"], api::to_string(row.type)) << path << " " << row.name;
      }
    }
  }
}

TEST(ParamTable, EverySchemeOptionHasARefineRow) {
  for (const SchemeEntry& entry : scheme_registry())
    for (const SchemeOptionSpec& option : entry.options) {
      const ParamRow* row = api::find_param(option.name);
      ASSERT_NE(row, nullptr) << entry.name << " " << option.name;
      EXPECT_TRUE(row->takes(RequestKind::Refine)) << entry.name << " " << option.name;
      EXPECT_FALSE(row->takes(RequestKind::Slice)) << option.name;
      // Two schemes reading an option of the same name declare it alike.
      const SchemeOptionSpec& first = *find_scheme_option(option.name);
      EXPECT_EQ(first.integer, option.integer) << option.name;
      EXPECT_EQ(first.default_value, option.default_value) << option.name;
      EXPECT_EQ(first.minimum, option.minimum) << option.name;
      EXPECT_EQ(first.maximum, option.maximum) << option.name;
      EXPECT_EQ(first.exclusive_minimum, option.exclusive_minimum) << option.name;
      // Its default is inside its range, and the scheme is made with it.
      EXPECT_NO_THROW(option.check(option.default_value)) << option.name;
      EXPECT_NO_THROW(make_scheme(entry.name, SchemeOptions{{option.name, option.default_value}}));
    }
  EXPECT_EQ(api::schemes_using("kappa"), std::vector<std::string_view>{"loop-g2"});
  EXPECT_EQ(api::schemes_using("alpha"), std::vector<std::string_view>{"sqrt3-unified"});
  EXPECT_TRUE(api::schemes_using("levels").empty());
}

// Each row's declared range (the CLI help's and the OpenAPI document's) is the one its reader
// enforces: both ends accepted, just outside them refused naming the row.
TEST(ParamTable, EveryRangeIsTheOneItsReaderEnforces) {
  api::RequestLimits limits;
  limits.accept_threads = true;
  limits.max_faces = (std::uint64_t{1} << 31) - 1;
  const auto parse = [&](const ParamRow& row, double value) {
    std::ostringstream text;
    text << std::setprecision(17) << value;
    const std::string name(row.name);
    if (row.takes(RequestKind::Refine)) {
      api::RawParams raw = {{name, text.str()}};
      if (name == "max_layers") raw.emplace_back("layer_height", "1");  // it needs one
      api::parse_refine_params(raw, limits);
    } else if (row.takes(RequestKind::Slice)) {
      api::parse_slice_params({{name, text.str()}}, limits);
    } else {
      api::parse_info_params({{name, text.str()}});
    }
  };
  const auto refused = [&](const ParamRow& row, double value) {
    try {
      parse(row, value);
      ADD_FAILURE() << row.name << " = " << value << " accepted, outside " << api::range_text(row);
    } catch (const Error& e) {
      EXPECT_EQ(e.field(), row.name) << row.name << " = " << value;
      EXPECT_TRUE(e.reason() == "out_of_range" || e.reason() == "not_a_number" ||
                  e.reason() == "above_server_cap")
          << row.name << " " << e.reason();
    }
  };
  int ranged = 0;
  for (const ParamRow& row : api::param_table()) {
    if (!row.minimum && !row.maximum) continue;
    ++ranged;
    const bool integer = row.type == api::ParamType::Integer;
    const auto step = [&](double v) { return integer ? 1.0 : std::max(std::abs(v) * 1e-6, 1e-9); };
    if (row.minimum) {
      const double lo = *row.minimum;
      if (row.exclusive_minimum) {
        refused(row, lo);
        EXPECT_NO_THROW(parse(row, lo + step(lo))) << row.name;
      } else {
        EXPECT_NO_THROW(parse(row, lo)) << row.name;
        refused(row, lo - step(lo));
      }
    }
    if (row.maximum) {
      const double hi = *row.maximum;
      EXPECT_NO_THROW(parse(row, hi)) << row.name;
      refused(row, hi + step(hi));
    }
  }
  EXPECT_GE(ranged, 12);
}

// A default given as its value is accepted, and is the value a request without it gets.
TEST(ParamTable, EveryDefaultIsAcceptedAndIsTheDefault) {
  api::RequestLimits cli;
  cli.accept_threads = true;
  const api::RequestLimits daemon;
  const api::RefineRequest none = api::parse_refine_params({}, cli);
  for (const ParamRow& row : api::param_table()) {
    const std::string value = api::default_text(row);
    if (value.empty()) continue;
    const api::RawParams raw = {{std::string(row.name), value}};
    // The daemon's rows with the daemon's limits (the CLI does not take them).
    const api::RequestLimits& limits = row.http_only ? daemon : cli;
    if (row.takes(RequestKind::Refine)) {
      api::RawParams refine_raw = raw;
      // The slicing modifiers need a layer height.
      if (row.name == "slice_format" || row.name == "max_layers" || row.name == "z_min" ||
          row.name == "z_max")
        refine_raw.emplace_back("layer_height", "0.5");
      api::RefineRequest given;
      ASSERT_NO_THROW(given = api::parse_refine_params(refine_raw, limits)) << row.name;
      // The refinement is made the same way with and without it.
      if (!row.scheme_option) {
        EXPECT_EQ(given.refine.scheme, none.refine.scheme) << row.name;
        EXPECT_EQ(given.refine.levels, none.refine.levels) << row.name;
        EXPECT_EQ(given.refine.max_level, none.refine.max_level) << row.name;
        EXPECT_EQ(given.refine.adaptive_tol, none.refine.adaptive_tol) << row.name;
        EXPECT_EQ(given.refine.adaptive_angle, none.refine.adaptive_angle) << row.name;
        EXPECT_EQ(given.refine.features.crease_mode, none.refine.features.crease_mode) << row.name;
        EXPECT_EQ(given.weld_tolerance, none.weld_tolerance) << row.name;
        EXPECT_EQ(given.primitives.enabled, none.primitives.enabled) << row.name;
        EXPECT_EQ(given.primitives.tolerance, none.primitives.tolerance) << row.name;
        EXPECT_EQ(given.primitives.max_deviation, none.primitives.max_deviation) << row.name;
        EXPECT_EQ(given.primitives.measure, none.primitives.measure) << row.name;
        EXPECT_EQ(given.refine.threads, none.refine.threads) << row.name;
        EXPECT_EQ(given.units.units, none.units.units) << row.name;
        EXPECT_EQ(given.units.scale, none.units.scale) << row.name;
      }
    }
    if (row.takes(RequestKind::Slice)) {
      const api::SliceRequest given = api::parse_slice_params(raw, limits);
      const api::SliceRequest absent = api::parse_slice_params({}, cli);
      EXPECT_EQ(given.slice.params.layer_height, absent.slice.params.layer_height) << row.name;
      EXPECT_EQ(given.slice.params.max_layers, absent.slice.params.max_layers) << row.name;
      EXPECT_EQ(given.slice.format, absent.slice.format) << row.name;
      EXPECT_EQ(given.weld_tolerance, absent.weld_tolerance) << row.name;
    }
  }
}

// The OpenAPI document carries each row's range and default.
TEST(ParamTable, TheOpenApiDocumentCarriesRangesAndDefaults) {
  const nlohmann::json doc = nlohmann::json::parse(server::openapi_document());
  const nlohmann::json& params = doc["paths"]["/v1/refine"]["post"]["parameters"];
  const auto schema_of = [&](std::string_view name) {
    for (const nlohmann::json& p : params)
      if (p["name"] == name) return p["schema"];
    return nlohmann::json();
  };
  EXPECT_EQ(schema_of("levels")["minimum"], 0);
  EXPECT_EQ(schema_of("levels")["maximum"], 8);
  EXPECT_EQ(schema_of("levels")["default"], 1);
  EXPECT_EQ(schema_of("kappa")["minimum"], 0.0);
  EXPECT_EQ(schema_of("kappa")["exclusiveMinimum"], true);
  EXPECT_EQ(schema_of("kappa")["default"], 0.5);
  EXPECT_EQ(schema_of("ramp_steps")["type"], "integer");
  EXPECT_EQ(schema_of("scheme")["default"], "butterfly");
  EXPECT_EQ(schema_of("max_deviation")["default"], "auto");
}

}  // namespace
}  // namespace stlrefine::test
