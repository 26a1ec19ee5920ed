// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// The OpenAPI document passes a real validator (issue 19 item 6): JSON::Validator's OpenAPI
// 3 schema (tests/server/openapi_validate.pl), with 0 errors; and what a client generator
// needs is there: servers, an operationId on every operation (unique), the bearer scheme
// applied, each parameter's type, and the headers clients read.

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <string>

#include "server/daemon.h"
#include "subprocess.h"

namespace stlrefine::test {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

ProcessResult validate(const std::string& document) {
  const fs::path file =
      fs::temp_directory_path() / ("stlrefine_openapi_" + std::to_string(::getpid()) + ".json");
  std::ofstream(file) << document;
  ProcessResult r =
      run_process({"/usr/bin/perl", STLREFINE_OPENAPI_VALIDATOR, file.string()}, 120s);
  fs::remove(file);
  return r;
}

TEST(OpenApiValidator, TheDocumentHasNoError) {
  const ProcessResult r = validate(server::openapi_document());
  ASSERT_EQ(r.err.find("Can't locate"), std::string::npos)
      << "the validator needs libjson-validator-perl (scripts/setup.sh installs it): " << r.err;
  EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("0 errors"), std::string::npos) << r.out;
}

TEST(OpenApiValidator, CatchesABrokenDocument) {
  // The validator is not a formality: a response without its description is an error.
  nlohmann::json doc = nlohmann::json::parse(server::openapi_document());
  doc["paths"]["/v1/refine"]["post"]["responses"]["200"].erase("description");
  const ProcessResult r = validate(doc.dump());
  EXPECT_EQ(r.exit_code, 1) << r.out << r.err;
  EXPECT_NE(r.out.find("/paths/~1v1~1refine/post/responses/200"), std::string::npos) << r.out;
}

TEST(OpenApiValidator, WhatAClientGeneratorNeeds) {
  const nlohmann::json doc = nlohmann::json::parse(server::openapi_document());
  ASSERT_TRUE(doc.contains("servers"));
  EXPECT_EQ(doc["security"][0].count("bearer"), 1u);
  std::set<std::string> ids;
  for (const auto& [path, item] : doc["paths"].items())
    for (const auto& [method, op] : item.items()) {
      if (method == "parameters") continue;
      ASSERT_TRUE(op.contains("operationId")) << method << " " << path;
      EXPECT_TRUE(ids.insert(op["operationId"].get<std::string>()).second)
          << "operationId given twice: " << op["operationId"];
      for (const auto& p : op.value("parameters", nlohmann::json::array()))
        EXPECT_TRUE(p["schema"].contains("type")) << path << " " << p["name"];
    }
  const auto& refine = doc["paths"]["/v1/refine"]["post"];
  EXPECT_EQ(refine["operationId"], "refine");
  EXPECT_TRUE(refine["responses"]["200"]["content"].contains("application/zip"));
  EXPECT_TRUE(refine["responses"]["200"]["headers"].contains("X-Stlrefine-Report"));
  EXPECT_TRUE(refine["responses"]["503"]["headers"].contains("Retry-After"));
  EXPECT_TRUE(doc["paths"]["/v1/jobs"]["post"]["responses"]["202"]["headers"].contains("Location"));
  EXPECT_TRUE(
      doc["paths"]["/v1/slice"]["post"]["responses"]["200"]["content"].contains("image/svg+xml"));
  EXPECT_EQ(doc["paths"]["/healthz"]["get"]["security"], nlohmann::json::array());
}

}  // namespace
}  // namespace stlrefine::test
