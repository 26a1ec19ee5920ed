// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// api::parse_query, the daemon's query string parser, and the fuzz_query finding that made
// it: httplib's parse_query_text kept only the last '='-part of a value, so
// "crease_angle=<bytes>=0" was accepted as crease_angle 0, and the job store then failed to
// write the raw query (invalid UTF-8) into its JSON record: a 500 on POST /v1/jobs.

#include <gtest/gtest.h>

#include <chrono>
#include <csignal>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>

#include "api/params.h"
#include "api/problem.h"
#include "http_test_client.h"
#include "server/daemon.h"
#include "test_stl.h"

namespace stlrefine::api {
namespace {

using Pairs = RawParams;

Error query_error(std::string_view query) {
  try {
    parse_refine_params(parse_query(query), RequestLimits{});
  } catch (const Error& e) {
    return e;
  }
  ADD_FAILURE() << "no error for " << query;
  return Error(ErrorCode::Internal, "none", "none");
}

TEST(ApiQuery, KeepsArrivalOrderAndDuplicates) {
  EXPECT_EQ(parse_query("levels=2&scheme=loop&levels=2"),
            (Pairs{{"levels", "2"}, {"scheme", "loop"}, {"levels", "2"}}));
  EXPECT_EQ(parse_query(""), Pairs{});
  EXPECT_EQ(parse_query("&&levels=1&"), (Pairs{{"levels", "1"}}));
  EXPECT_EQ(parse_query("levels"), (Pairs{{"levels", ""}}));
}

TEST(ApiQuery, DecodesPercentAndPlus) {
  EXPECT_EQ(parse_query("heights=0.1%2C0.2%2c+0.3&sch%65me=loop"),
            (Pairs{{"heights", "0.1,0.2, 0.3"}, {"scheme", "loop"}}));
  // Not an escape: kept as written, and then refused as not a number.
  EXPECT_EQ(parse_query("a=%zz&b=%4&c=%"), (Pairs{{"a", "%zz"}, {"b", "%4"}, {"c", "%"}}));
  EXPECT_EQ(parse_query("a=%00%FF"), (Pairs{{"a", std::string("\0\xff", 2)}}));
}

TEST(ApiQuery, EverythingAfterTheFirstEqualsIsTheValue) {
  EXPECT_EQ(parse_query("levels=1=2"), (Pairs{{"levels", "1=2"}}));
  const Error e = query_error("levels=1=2");
  EXPECT_EQ(e.field(), "levels");
  EXPECT_EQ(e.reason(), "not_a_number");
}

TEST(ApiQuery, NamelessPairsAndRepeatedPairsAreRefused) {
  for (const char* query : {"=5", "levels=1&=x", "%3D=1&="}) {
    SCOPED_TRACE(query);
    try {
      parse_query(query);
      ADD_FAILURE() << "accepted";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::InvalidParameter);
      EXPECT_EQ(e.field(), "query");
      EXPECT_EQ(e.reason(), "malformed_query");
    }
  }
  // A name that decodes to '=' is a name (an unknown one).
  EXPECT_EQ(parse_query("%3D=1"), (Pairs{{"=", "1"}}));
  // httplib merged identical pairs; they are a duplicate like any other.
  EXPECT_EQ(query_error("levels=1&levels=1").reason(), "duplicate_parameter");
}

// fuzz_query's crash input (crash-816f06de...), a refusal naming the field.
TEST(ApiQuery, FuzzFoundValueWithBytesBeforeAnEqualsIsRefused) {
  const std::string query =
      "crease_angle=\xc3\xfe\x91\xca\x9e\x9b\x9e\xc9"
      "666666oance=0";
  const Error e = query_error(query);
  EXPECT_EQ(e.code(), ErrorCode::InvalidParameter);
  EXPECT_EQ(e.field(), "crease_angle");
  const std::string body = problem_body(problem_from_error(e));
  EXPECT_EQ(nlohmann::json::parse(body).at("field"), "crease_angle");
}

}  // namespace
}  // namespace stlrefine::api

namespace stlrefine::server {
namespace {

using namespace std::chrono_literals;

// The same request against the daemon with jobs enabled: 400 on both routes, not a 500.
TEST(DaemonQuery, FuzzFoundQueryIs400OnRefineAndJobs) {
  std::signal(SIGPIPE, SIG_IGN);
  const auto dir =
      std::filesystem::temp_directory_path() / ("stlrefine-query-" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  DaemonConfig config;
  config.compute_slots = 1;
  config.jobs.data_dir = dir;
  Daemon daemon(config);
  const int port = daemon.bind("127.0.0.1", 0);
  std::thread thread([&] { daemon.run(); });

  const std::string stl = test::binary_stl(test::octahedron_triangles());
  for (const char* route : {"/v1/refine", "/v1/jobs"}) {
    SCOPED_TRACE(route);
    const std::string target = std::string(route) + "?crease_angle=\xc3\xfe=0";
    const auto responses =
        test::parse_responses(test::exchange(port, test::post_text(target, "model/stl", stl)));
    ASSERT_EQ(responses.size(), 1u);
    EXPECT_EQ(responses[0].status, 400);
    EXPECT_EQ(nlohmann::json::parse(responses[0].body).at("field"), "crease_angle");
  }
  daemon.stop();
  thread.join();
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace stlrefine::server
