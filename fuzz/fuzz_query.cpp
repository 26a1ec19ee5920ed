// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors

// libFuzzer harness: the query string of every route, as the daemon takes it
// (api::parse_query, what server/daemon.cpp's raw_params calls), through api/'s parameter
// parsers with the daemon's and the CLI's limits, to the problem body a refusal becomes,
// and for accepted parameters to the first things the daemon does with them (the face
// budget, the slice plan, the job record).

#include <algorithm>
#include <array>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>

#include "api/params.h"
#include "api/problem.h"
#include "core/mesh/build_mesh.h"
#include "fuzz/fuzz_check.h"

using namespace stlrefine;

namespace {

// A refused query is a 400 whose body is ASCII JSON naming the field.
void check_problem(const Error& e) {
  fuzz::check_refusal(e);
  fuzz::check(e.code() == ErrorCode::InvalidParameter,
              "a parameter error that is not a 400:", e.what());
  fuzz::check(!e.field().empty(), "a parameter error without a field:", e.what());
  const api::Problem problem = api::problem_from_error(e);
  fuzz::check(problem.status == 400, "a parameter error that is not a 400:", e.what());
  const std::string body = api::problem_body(problem);
  for (const char c : body) fuzz::check(static_cast<unsigned char>(c) < 0x80, "non-ASCII body");
  const auto parsed = nlohmann::json::parse(body, nullptr, /*allow_exceptions=*/false);
  fuzz::check(!parsed.is_discarded(), "the problem body is not JSON:", body.c_str());
  fuzz::check(parsed.value("status", 0) == 400, "status member is not 400");
  fuzz::check(parsed.contains("field"), "the problem body names no field");
}

// A 2 mm tetrahedron at z in [0, 2]: what plan_layers and the budget check see.
const Mesh& small_part() {
  static const Mesh mesh = [] {
    IndexedSoup soup;
    soup.positions = {{0, 0, 0}, {2, 0, 0}, {0, 2, 0}, {0, 0, 2}};
    soup.triangles = {{{0, 2, 1}}, {{0, 1, 3}}, {{0, 3, 2}}, {{1, 2, 3}}};
    return build_mesh(soup).mesh;
  }();
  return mesh;
}

// What the daemon does with an accepted slice plan once it has the mesh. The layer cap is
// lowered from 1'000'000 so that large plans (8 MB of heights each) are refused rather
// than built: that keeps an execution cheap and still reaches the budget check.
void plan(slicer::SliceParams params) {
  params.max_layers = std::min<std::size_t>(params.max_layers, 4096);
  try {
    const slicer::SlicePlan p = slicer::plan_layers(small_part(), params);
    fuzz::check(p.heights.size() <= params.max_layers, "plan over max_layers");
  } catch (const Error& e) {
    fuzz::check_refusal(e);
    // NothingToMake: a uniform layer height taller than the part (a 422 naming the field).
    fuzz::check(e.code() == ErrorCode::BudgetExceeded || e.code() == ErrorCode::InvalidParameter ||
                    e.code() == ErrorCode::NothingToMake,
                "plan_layers threw an unexpected error:", e.what());
    if (e.code() == ErrorCode::NothingToMake)
      fuzz::check(!e.field().empty(), "a nothing-to-make error without a field:", e.what());
  }
}

void refine_route(const api::RawParams& raw, const api::RequestLimits& limits,
                  const std::string& query) {
  api::RefineRequest request;
  try {
    request = api::parse_refine_params(raw, limits);
  } catch (const Error& e) {
    check_problem(e);
    return;
  }
  fuzz::check(request.refine.max_faces <= limits.max_faces, "max_faces above the cap");
  try {
    request.refine.validate();
    check_face_budget(1'000'000, request.refine);
  } catch (const Error& e) {
    fuzz::check_refusal(e);
    fuzz::check(e.code() == ErrorCode::BudgetExceeded,
                "accepted parameters fail validation:", e.what());
  }
  if (request.slice) plan(request.slice->params);
  // The job store keeps the raw query in its JSON record (server/jobs.cpp).
  nlohmann::json record;
  record["parameters"] = query;
  (void)record.dump(2);
}

void slice_route(const api::RawParams& raw, const api::RequestLimits& limits) {
  try {
    const api::SliceRequest request = api::parse_slice_params(raw, limits);
    plan(request.slice.params);
  } catch (const Error& e) {
    check_problem(e);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string query(reinterpret_cast<const char*>(data), size);
  api::RawParams raw;
  try {
    raw = api::parse_query(query);
  } catch (const Error& e) {
    check_problem(e);
    return 0;
  }

  // The daemon's limits (server/daemon.cpp) and the CLI's (cli/main.cpp).
  const api::RequestLimits daemon{.max_faces = 20'000'000,
                                  .default_max_faces = 0,
                                  .max_slice_points = 20'000'000,
                                  .accept_threads = false};
  const api::RequestLimits cli{.max_faces = (std::uint64_t{1} << 31) - 1,
                               .default_max_faces = RefineParams{}.max_faces,
                               .max_slice_points = slicer::SliceParams{}.max_points,
                               .accept_threads = true};
  try {
    const api::InfoRequest info = api::parse_info_params(raw);
    info.features.validate();
  } catch (const Error& e) {
    check_problem(e);
  }
  for (const api::RequestLimits& limits : {daemon, cli}) {
    refine_route(raw, limits, query);
    slice_route(raw, limits);
  }
  return 0;
}
