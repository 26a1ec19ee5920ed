// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "api/problem.h"

namespace stlrefine::api {
namespace {

TEST(ApiProblem, StatusPerErrorCode) {
  EXPECT_EQ(http_status(ErrorCode::InvalidParameter), 400);
  EXPECT_EQ(http_status(ErrorCode::MalformedStl), 422);
  EXPECT_EQ(http_status(ErrorCode::NotTriangleMesh), 422);
  EXPECT_EQ(http_status(ErrorCode::BudgetExceeded), 422);
  EXPECT_EQ(http_status(ErrorCode::Cancelled), 503);
  EXPECT_EQ(http_status(ErrorCode::Internal), 500);
}

TEST(ApiProblem, ParameterErrorNamesTheField) {
  const Problem p = problem_from_error(
      Error(ErrorCode::InvalidParameter, "out_of_range", "levels = 9 is outside [0, 8]")
          .with_field("levels"));
  const nlohmann::json j = nlohmann::json::parse(problem_body(p));
  EXPECT_EQ(j.at("type"), "urn:stlrefine:problem:invalid-parameter");
  EXPECT_EQ(j.at("title"), "Invalid parameter");
  EXPECT_EQ(j.at("status"), 400);
  EXPECT_EQ(j.at("detail"), "levels = 9 is outside [0, 8]");
  EXPECT_EQ(j.at("field"), "levels");
  EXPECT_EQ(j.at("reason"), "out_of_range");
  EXPECT_FALSE(j.contains("byte_offset"));
  EXPECT_FALSE(j.contains("line"));
}

TEST(ApiProblem, StlErrorCarriesItsLocation) {
  Problem p = problem_from_error(Error(ErrorCode::MalformedStl, "non_finite", "NaN").at_byte(150));
  nlohmann::json j = nlohmann::json::parse(problem_body(p));
  EXPECT_EQ(j.at("status"), 422);
  EXPECT_EQ(j.at("type"), std::string(kProblemTypePrefix) + "malformed-stl");
  EXPECT_EQ(j.at("title"), "Malformed mesh file");  // OBJ, PLY, 3MF and zips share it
  EXPECT_EQ(j.at("byte_offset"), 150);
  EXPECT_FALSE(j.contains("field"));

  p = problem_from_error(Error(ErrorCode::MalformedStl, "syntax", "bad").at_line(6));
  j = nlohmann::json::parse(problem_body(p));
  EXPECT_EQ(j.at("line"), 6);
}

TEST(ApiProblem, BudgetCarriesThePrediction) {
  const Error core(ErrorCode::BudgetExceeded, "face_budget", "too many");
  const Problem p = problem_from_error(FaceBudgetError(core, 524288, 1000));
  const nlohmann::json j = nlohmann::json::parse(problem_body(p));
  EXPECT_EQ(j.at("status"), 422);
  EXPECT_EQ(j.at("type"), "urn:stlrefine:problem:budget-exceeded");
  EXPECT_EQ(j.at("predicted_faces"), 524288);
  EXPECT_EQ(j.at("max_faces"), 1000);
}

TEST(ApiProblem, InternalErrorsHideTheirText) {
  const Problem p = problem_from_error(Error(ErrorCode::Internal, "bug", "secret invariant"));
  EXPECT_EQ(p.status, 500);
  EXPECT_EQ(problem_body(p).find("secret"), std::string::npos);
}

TEST(ApiProblem, BodyIsAsciiEvenForHostileDetails) {
  const Problem p = make_problem(400, "bad-request", "caf\xc3\xa9 \xff\r\n");
  const std::string body = problem_body(p);
  for (unsigned char c : body) EXPECT_LT(c, 0x80);
  EXPECT_EQ(body.find('\n'), std::string::npos);
  EXPECT_TRUE(nlohmann::json::accept(body));
}

TEST(ApiProblem, TitlesFollowTheStatus) {
  EXPECT_EQ(make_problem(411, "length-required", "x").title, "Length required");
  EXPECT_EQ(make_problem(503, "busy", "x").title, "Service unavailable");
  EXPECT_EQ(make_problem(431, "header-fields-too-large", "x").title,
            "Request header fields too large");
}

}  // namespace
}  // namespace stlrefine::api
