// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// Every parameter of every endpoint with absurd values (huge, negative, NaN, inf, 1e308,
// overflowing integers, ...), alone and next to the parameters that make it matter, through
// the parser and then the pipeline. Whatever refuses it, a 4xx must say which parameter
// (issue 16, item 8: a huge weld_tolerance got a 422 without `field`). A table: a new
// parameter or value is one more row.

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <functional>
#include <set>
#include <span>
#include <string>
#include <vector>

#include "api/params.h"
#include "api/pipeline.h"
#include "api/problem.h"
#include "core/error.h"
#include "test_stl.h"

namespace stlrefine::api {
namespace {

std::span<const std::uint8_t> bytes_of(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

const std::vector<std::string> kAbsurd = {"1e308",
                                          "-1e308",
                                          "1.7976931348623157e308",
                                          "-1.7976931348623157e308",
                                          "1e309",
                                          "1e999",
                                          "-1e999",
                                          "nan",
                                          "NaN",
                                          "-nan",
                                          "inf",
                                          "-inf",
                                          "infinity",
                                          "4.9e-324",
                                          "1e-308",
                                          "-1e-308",
                                          "-1",
                                          "-0",
                                          "0",
                                          "1e6",
                                          "1e12",
                                          "2147483648",
                                          "-2147483649",
                                          "9223372036854775807",
                                          "9223372036854775808",
                                          "-9223372036854775809",
                                          "18446744073709551615",
                                          "18446744073709551616",
                                          "",
                                          "0x10",
                                          " 1",
                                          "1,1e308",
                                          "nan,1",
                                          "1,1"};

// What makes a parameter matter: a scheme that reads it, the adaptive mode, a slice.
const std::vector<RawParams> kRefineContexts = {{},
                                                {{"scheme", "sqrt3-unified"}},
                                                {{"scheme", "loop-g2"}},
                                                {{"adaptive_tol", "0.01"}},
                                                {{"scheme", "loop"}, {"adaptive_angle", "10"}},
                                                {{"slice", "0.5"}},
                                                {{"slice", "0.5"}, {"slice_format", "svg"}}};
const std::vector<RawParams> kSliceContexts = {
    {}, {{"format", "svg"}}, {{"format", "cli-binary"}}, {{"z_min", "-1"}}, {{"z_max", "1"}}};

// The budgets a 422 may name instead of a parameter (server/README, "Errors").
const std::set<std::string> kBudgets = {"max_faces", "max_points", "max_layers"};

struct Endpoint {
  const char* name;
  std::vector<std::string_view> params;
  std::vector<RawParams> contexts;
  // Parses, then runs the pipeline on the octahedron.
  std::function<void(const RawParams&)> run;
};

RequestLimits limits() {
  RequestLimits l;
  l.max_faces = 200'000;  // small answers: every accepted row runs in milliseconds
  l.max_slice_points = 2'000'000;
  l.accept_threads = true;  // the CLI's set, a superset of the daemon's
  return l;
}

std::vector<Endpoint> endpoints() {
  const std::string stl = test::binary_stl(test::octahedron_triangles());
  return {
      {"info",
       {info_param_names().begin(), info_param_names().end()},
       {{}},
       [stl](const RawParams& raw) { run_info(bytes_of(stl), parse_info_params(raw)); }},
      {"refine", refine_param_names(limits()), kRefineContexts,
       [stl](const RawParams& raw) {
         RefineRequest r = parse_refine_params(raw, limits());
         r.refine.threads = 1;
         if (r.slice) r.slice->params.threads = 1;
         run_refine(bytes_of(stl), r);
       }},
      {"slice", slice_param_names(limits()), kSliceContexts,
       [stl](const RawParams& raw) {
         SliceRequest r = parse_slice_params(raw, limits());
         r.slice.params.threads = 1;
         run_slice(bytes_of(stl), r);
       }},
  };
}

TEST(ApiAbsurdParams, EveryRefusalNamesItsField) {
  std::size_t rows = 0, refused = 0;
  for (const Endpoint& endpoint : endpoints()) {
    std::set<std::string> known(endpoint.params.begin(), endpoint.params.end());
    for (const std::string_view param : endpoint.params) {
      for (const RawParams& context : endpoint.contexts) {
        if (std::any_of(context.begin(), context.end(),
                        [&](const auto& kv) { return kv.first == param; }))
          continue;
        for (const std::string& value : kAbsurd) {
          RawParams raw = context;
          raw.emplace_back(std::string(param), value);
          std::string row = std::string(endpoint.name) + ":";
          for (const auto& [n, v] : raw) row += " " + n + "=" + v;
          ++rows;
          try {
            endpoint.run(raw);
          } catch (const Error& e) {
            ++refused;
            const Problem p = problem_from_error(e);
            EXPECT_TRUE(p.status >= 400 && p.status < 500)
                << row << " -> " << p.status << " " << e.what();
            EXPECT_FALSE(p.field.empty()) << row << " -> " << p.status << " " << e.what();
            EXPECT_TRUE(known.contains(p.field) || kBudgets.contains(p.field))
                << row << " -> field '" << p.field << "', not a parameter of " << endpoint.name;
            // A parameter's own refusal names it (not a neighbour or a budget).
            if (e.code() == ErrorCode::InvalidParameter && p.field != param) {
              const bool in_context = std::any_of(context.begin(), context.end(),
                                                  [&](auto& kv) { return kv.first == p.field; });
              EXPECT_TRUE(in_context) << row << " -> field '" << p.field << "': " << e.what();
            }
          }
        }
      }
    }
  }
  EXPECT_GT(rows, 1000u);
  EXPECT_GT(refused, rows / 2);  // the table is absurd: most rows must be refused
}

TEST(ApiAbsurdParams, AHugeWeldToleranceIsA422NamingIt) {
  // The row of the issue, on each endpoint: every corner welds into one, so no triangle is
  // left; today build_mesh's "no_faces" came without a field.
  for (const char* tolerance : {"1e308", "1.7976931348623157e308", "1e30", "2"}) {
    SCOPED_TRACE(tolerance);
    const RawParams raw = {{"weld_tolerance", tolerance}};
    for (const Endpoint& endpoint : endpoints()) {
      try {
        endpoint.run(raw);
        ADD_FAILURE() << endpoint.name << " accepted";
      } catch (const Error& e) {
        const Problem p = problem_from_error(e);
        EXPECT_EQ(p.status, 422) << endpoint.name << ": " << e.what();
        EXPECT_EQ(p.field, "weld_tolerance") << endpoint.name << ": " << e.what();
        EXPECT_EQ(e.reason(), "weld_collapsed") << endpoint.name;
      }
    }
  }
  // Below the part's size it welds as before.
  EXPECT_NO_THROW(endpoints()[0].run({{"weld_tolerance", "0.5"}}));
}

}  // namespace
}  // namespace stlrefine::api
