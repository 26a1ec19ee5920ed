// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// The parameter table (api/param_table.h) reaches all three of its users: every row is an
// option in the CLI's help, is accepted by the query parser, and is in the OpenAPI document
// of every route that takes it; and every option a scheme's registry row names has a row.

#include "api/param_table.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
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
      // `slice_format` needs `slice`; every other row accepts it beside itself.
      api::RawParams raw = {{name, value}};
      if (name != "slice") raw.emplace_back("slice", "0.5");
      EXPECT_NO_THROW(api::parse_refine_params(raw, cli)) << name;
      if (row.cli_only) {
        EXPECT_THROW(api::parse_refine_params(raw, daemon), Error) << name;
      } else {
        EXPECT_NO_THROW(api::parse_refine_params(raw, daemon)) << name;
      }
    }
    if (row.takes(RequestKind::Slice)) {
      EXPECT_NO_THROW(api::parse_slice_params({{name, value}}, cli)) << name;
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
    for (std::string_view option : entry.options) {
      const ParamRow* row = api::find_param(option);
      ASSERT_NE(row, nullptr) << entry.name << " " << option;
      EXPECT_TRUE(row->takes(RequestKind::Refine)) << entry.name << " " << option;
    }
  EXPECT_EQ(api::schemes_using("kappa"), std::vector<std::string_view>{"loop-g2"});
  EXPECT_EQ(api::schemes_using("alpha"), std::vector<std::string_view>{"sqrt3-unified"});
  EXPECT_TRUE(api::schemes_using("levels").empty());
}

}  // namespace
}  // namespace stlrefine::test
