// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "api/problem.h"

#include <utility>

namespace stlrefine::api {

namespace {

const char* title_for_status(int status) {
  switch (status) {
    case 400:
      return "Bad request";
    case 404:
      return "Not found";
    case 405:
      return "Method not allowed";
    case 408:
      return "Request timeout";
    case 411:
      return "Length required";
    case 413:
      return "Content too large";
    case 414:
      return "URI too long";
    case 415:
      return "Unsupported media type";
    case 416:
      return "Range not satisfiable";
    case 417:
      return "Expectation failed";
    case 422:
      return "Unprocessable content";
    case 431:
      return "Request header fields too large";
    case 500:
      return "Internal server error";
    case 503:
      return "Service unavailable";
    default:
      return status >= 500 ? "Server error" : "Client error";
  }
}

struct CodeInfo {
  const char* slug;
  const char* title;
};

CodeInfo info_for(ErrorCode code) {
  switch (code) {
    case ErrorCode::InvalidParameter:
      return {"invalid-parameter", "Invalid parameter"};
    case ErrorCode::MalformedStl:
      return {"malformed-stl", "Malformed STL"};
    case ErrorCode::NotTriangleMesh:
      return {"not-triangle-mesh", "Not a triangle mesh"};
    case ErrorCode::BudgetExceeded:
      return {"budget-exceeded", "Face budget exceeded"};
    case ErrorCode::Cancelled:
      return {"cancelled", "Request cancelled"};
    case ErrorCode::Internal:
      return {"internal", "Internal server error"};
  }
  return {"internal", "Internal server error"};
}

}  // namespace

int http_status(ErrorCode code) {
  switch (code) {
    case ErrorCode::InvalidParameter:
      return 400;
    case ErrorCode::MalformedStl:
      return 422;
    case ErrorCode::NotTriangleMesh:
      return 422;
    case ErrorCode::BudgetExceeded:
      return 422;
    case ErrorCode::Cancelled:
      return 503;  // only when the daemon shuts down
    case ErrorCode::Internal:
      return 500;
  }
  return 500;
}

Problem problem_from_error(const Error& error) {
  const CodeInfo info = info_for(error.code());
  Problem p;
  p.status = http_status(error.code());
  p.slug = info.slug;
  p.title = info.title;
  p.detail = error.code() == ErrorCode::Internal ? "an internal error occurred" : error.what();
  p.field = error.field();
  p.byte_offset = error.byte_offset();
  p.line = error.line();
  if (!error.reason().empty()) p.extensions["reason"] = error.reason();
  // The slicer's budgets share the code (and the 422) with the face budget.
  if (error.code() == ErrorCode::BudgetExceeded && error.field() == "max_layers")
    p.title = "Layer budget exceeded";
  if (error.code() == ErrorCode::BudgetExceeded && error.field() == "max_points")
    p.title = "Point budget exceeded";
  if (error.code() == ErrorCode::BudgetExceeded && error.reason() == "memory_budget")
    p.title = "Memory budget exceeded";
  if (const auto* budget = dynamic_cast<const FaceBudgetError*>(&error)) {
    p.extensions["predicted_faces"] = budget->predicted_faces();
    p.extensions["max_faces"] = budget->max_faces();
  }
  return p;
}

Problem make_problem(int status, std::string slug, std::string detail) {
  Problem p;
  p.status = status;
  p.slug = std::move(slug);
  p.title = title_for_status(status);
  p.detail = std::move(detail);
  return p;
}

nlohmann::ordered_json to_json(const Problem& problem) {
  nlohmann::ordered_json j;
  j["type"] = std::string(kProblemTypePrefix) + problem.slug;
  j["title"] = problem.title;
  j["status"] = problem.status;
  j["detail"] = problem.detail;
  if (!problem.field.empty()) j["field"] = problem.field;
  if (problem.byte_offset) j["byte_offset"] = *problem.byte_offset;
  if (problem.line) j["line"] = *problem.line;
  if (problem.extensions.is_object())
    for (const auto& [key, value] : problem.extensions.items())
      if (!j.contains(key)) j[key] = value;
  return j;
}

std::string problem_body(const Problem& problem) {
  // ensure_ascii: details echo user input; replace invalid UTF-8 instead of throwing.
  return to_json(problem).dump(-1, ' ', true, nlohmann::ordered_json::error_handler_t::replace);
}

}  // namespace stlrefine::api
