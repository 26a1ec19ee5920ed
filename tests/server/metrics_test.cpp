// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// GET /metrics is unauthenticated: no request may add a series (issue 16, item 6). Random
// methods, paths, statuses, schemes and outcomes must all land on a fixed set of labels.

#include "server/metrics.h"

#include <gtest/gtest.h>

#include <climits>
#include <cstddef>
#include <map>
#include <random>
#include <regex>
#include <set>
#include <sstream>
#include <string>

#include "core/schemes/registry.h"

namespace stlrefine::server {
namespace {

std::string random_text(std::mt19937_64& rng, std::size_t max_length) {
  std::uniform_int_distribution<std::size_t> length(1, max_length);
  std::uniform_int_distribution<int> byte(0, 255);
  std::string s(length(rng), '\0');
  for (char& c : s) c = static_cast<char>(byte(rng));
  return s;
}

// What a client can put in a request line: methods and paths of any bytes and length,
// sometimes close to a real one.
std::string random_method(std::mt19937_64& rng) {
  static const char* const kNear[] = {"get", "PATCH", "PUT", "TRACE", "CONNECT", "GET ", "POST\n"};
  if (rng() % 4 == 0) return kNear[rng() % std::size(kNear)];
  return random_text(rng, 64);
}

std::string random_path(std::mt19937_64& rng) {
  static const char* const kPrefixes[] = {"/", "/v1/", "/v1/jobs/", "/assets/", "/v1/refine/", ""};
  return kPrefixes[rng() % std::size(kPrefixes)] + random_text(rng, 200);
}

int random_status(std::mt19937_64& rng) {
  static const int kStatuses[] = {200, 202, 400, 404, 405,  413,     422,    503,
                                  -1,  0,   99,  600, 1000, INT_MAX, INT_MIN};
  return kStatuses[rng() % std::size(kStatuses)];
}

void feed(Metrics& m, std::mt19937_64& rng, int n) {
  for (int i = 0; i < n; ++i) {
    m.request(route_label(random_path(rng)), random_method(rng), random_status(rng), 0.01);
    // A caller that forgets route_label must not add series either.
    m.request(random_path(rng), "GET", 200, 0.01);
    m.refinement(random_text(rng, 32), random_text(rng, 16), 0.5, 4, 16);
  }
}

std::size_t series(const std::string& text) {
  std::size_t n = 0;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) n += !line.empty() && line[0] != '#';
  return n;
}

TEST(Metrics, RandomMethodsPathsAndSchemesLeaveThePageSmall) {
  Metrics m;
  std::mt19937_64 rng(16);
  feed(m, rng, 3000);
  const std::string first = m.render({});
  // 13 route labels x 6 methods x 9 status labels, 9 schemes x 6 outcomes, at most: a
  // few hundred series and tens of KiB. Raw methods as labels made 6.2 MB of 3,000.
  EXPECT_LT(first.size(), 64u * 1024) << first.substr(0, 4096);
  // More of the same adds no series.
  feed(m, rng, 3000);
  const std::string second = m.render({});
  EXPECT_EQ(series(second), series(first));
  EXPECT_LT(second.size(), first.size() + 1024);
}

TEST(Metrics, EveryLabelValueComesFromAFixedSet) {
  Metrics m;
  std::mt19937_64 rng(6);
  feed(m, rng, 500);
  for (const char* method : {"GET", "HEAD", "POST", "DELETE", "OPTIONS"})
    m.request("/v1/refine", method, 200, 0.01);
  m.refinement("loop", "done", 1, 4, 16);

  std::map<std::string, std::set<std::string>> allowed = {
      {"route",
       {"/", "/healthz", "/readyz", "/metrics", "/v1/openapi.json", "/v1/refine", "/v1/slice",
        "/v1/info", "/v1/jobs", "/v1/jobs/{id}", "/v1/jobs/{id}/{file}", "/assets/{file}",
        "other"}},
      {"method", {"GET", "HEAD", "POST", "DELETE", "OPTIONS", "other"}},
      {"status", {"200", "202", "400", "404", "405", "413", "422", "503", "other"}},
      {"scheme", {"other"}},
      {"outcome", {"queued", "running", "done", "failed", "cancelled", "other"}}};
  for (std::string_view s : scheme_names()) allowed["scheme"].emplace(s);

  const std::string text = m.render({});
  const std::regex pair(R"re(([a-z_]+)="((?:[^"\\]|\\.)*)")re");
  std::set<std::string> seen_methods;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    for (std::sregex_iterator it(line.begin(), line.end(), pair), end; it != end; ++it) {
      const std::string name = (*it)[1], value = (*it)[2];
      if (name == "le") continue;  // histogram buckets: ours
      const auto set = allowed.find(name);
      ASSERT_NE(set, allowed.end()) << "unexpected label " << name << " in " << line;
      EXPECT_TRUE(set->second.contains(value)) << line;
      if (name == "method") seen_methods.insert(value);
    }
  }
  const std::set<std::string>& methods = allowed["method"];
  EXPECT_EQ(seen_methods, methods);  // the real methods keep their names
  EXPECT_NE(text.find(R"(stlrefine_refine_duration_seconds_count{scheme="loop",outcome="done"} 1)"),
            std::string::npos);
  EXPECT_NE(text.find(R"(route="other",method="other",status="other")"), std::string::npos);
}

TEST(Metrics, LabelFunctions) {
  EXPECT_EQ(metric_method("DELETE"), "DELETE");
  EXPECT_EQ(metric_method("delete"), "other");
  EXPECT_EQ(metric_method(""), "other");
  EXPECT_EQ(metric_status(404), "404");
  EXPECT_EQ(metric_status(42), "other");
  EXPECT_EQ(metric_scheme("butterfly"), "butterfly");
  EXPECT_EQ(metric_scheme("butterfly\"} 1\nx{"), "other");
  EXPECT_EQ(metric_outcome("failed"), "failed");
  EXPECT_EQ(metric_outcome("exploded"), "other");
  EXPECT_EQ(route_label("/v1/jobs/abc"), "/v1/jobs/{id}");
  EXPECT_EQ(route_label("/v1/jobs/abc/result.stl"), "/v1/jobs/{id}/{file}");
  EXPECT_EQ(route_label("/v1/refine/"), "other");
  EXPECT_EQ(route_label("/v1/refinex"), "other");
}

}  // namespace
}  // namespace stlrefine::server
