// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "api/problem.h"

#include <utility>

namespace stlrefine::api {

namespace {

// The one status table: the RFC 9110 reason phrase of the status line and the problem
// title. A null title: the generic "Client error" / "Server error" (statuses whose problems
// carry their own title, or never had one of their own).
struct StatusText {
  int status;
  const char* reason;
  const char* title;
};

constexpr StatusText kStatusTexts[] = {
    {http::kOk, "OK", nullptr},
    {http::kAccepted, "Accepted", nullptr},
    {http::kNoContent, "No Content", nullptr},
    {http::kPartialContent, "Partial Content", nullptr},
    {http::kNotModified, "Not Modified", nullptr},
    {http::kBadRequest, "Bad Request", "Bad request"},
    {http::kUnauthorized, "Unauthorized", nullptr},
    {http::kForbidden, "Forbidden", "Forbidden"},
    {http::kNotFound, "Not Found", "Not found"},
    {http::kMethodNotAllowed, "Method Not Allowed", "Method not allowed"},
    {http::kRequestTimeout, "Request Timeout", "Request timeout"},
    {http::kConflict, "Conflict", nullptr},
    {http::kGone, "Gone", nullptr},
    {http::kLengthRequired, "Length Required", "Length required"},
    {http::kContentTooLarge, "Content Too Large", "Content too large"},
    {http::kUriTooLong, "URI Too Long", "URI too long"},
    {http::kUnsupportedMediaType, "Unsupported Media Type", "Unsupported media type"},
    {http::kRangeNotSatisfiable, "Range Not Satisfiable", "Range not satisfiable"},
    {http::kExpectationFailed, nullptr, "Expectation failed"},
    {http::kUnprocessableContent, "Unprocessable Content", "Unprocessable content"},
    {http::kTooManyRequests, "Too Many Requests", "Too many requests"},
    {http::kHeaderFieldsTooLarge, "Request Header Fields Too Large",
     "Request header fields too large"},
    {http::kInternalServerError, "Internal Server Error", "Internal server error"},
    {http::kServiceUnavailable, "Service Unavailable", "Service unavailable"},
    {http::kGatewayTimeout, "Gateway Timeout", nullptr},
    {http::kInsufficientStorage, "Insufficient Storage", nullptr},
};

const StatusText* status_text(int status) {
  for (const StatusText& t : kStatusTexts)
    if (t.status == status) return &t;
  return nullptr;
}

const char* title_for_status(int status) {
  const StatusText* t = status_text(status);
  if (t && t->title) return t->title;
  return status >= 500 ? "Server error" : "Client error";
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
    case ErrorCode::NothingToMake:
      return {"nothing-to-make", "Nothing to make from this part"};
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
      return http::kBadRequest;
    case ErrorCode::MalformedStl:
      return http::kUnprocessableContent;
    case ErrorCode::NotTriangleMesh:
      return http::kUnprocessableContent;
    case ErrorCode::BudgetExceeded:
      return http::kUnprocessableContent;
    case ErrorCode::NothingToMake:
      return http::kUnprocessableContent;
    case ErrorCode::Cancelled:
      return http::kServiceUnavailable;  // only when the daemon shuts down
    case ErrorCode::Internal:
      return http::kInternalServerError;
  }
  return http::kInternalServerError;
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

const char* reason_phrase(int status) {
  const StatusText* t = status_text(status);
  if (t && t->reason) return t->reason;
  return status >= 500 ? "Server Error" : "Client Error";
}

#define STLREFINE_NAMED_PROBLEM(fn, status)                          \
  Problem fn(std::string slug, std::string detail) {                 \
    return make_problem(status, std::move(slug), std::move(detail)); \
  }
STLREFINE_NAMED_PROBLEM(bad_request, http::kBadRequest)
STLREFINE_NAMED_PROBLEM(unauthorized, http::kUnauthorized)
STLREFINE_NAMED_PROBLEM(forbidden, http::kForbidden)
STLREFINE_NAMED_PROBLEM(not_found, http::kNotFound)
STLREFINE_NAMED_PROBLEM(method_not_allowed, http::kMethodNotAllowed)
STLREFINE_NAMED_PROBLEM(request_timeout, http::kRequestTimeout)
STLREFINE_NAMED_PROBLEM(conflict, http::kConflict)
STLREFINE_NAMED_PROBLEM(gone, http::kGone)
STLREFINE_NAMED_PROBLEM(length_required, http::kLengthRequired)
STLREFINE_NAMED_PROBLEM(content_too_large, http::kContentTooLarge)
STLREFINE_NAMED_PROBLEM(uri_too_long, http::kUriTooLong)
STLREFINE_NAMED_PROBLEM(unsupported_media_type, http::kUnsupportedMediaType)
STLREFINE_NAMED_PROBLEM(range_not_satisfiable, http::kRangeNotSatisfiable)
STLREFINE_NAMED_PROBLEM(header_fields_too_large, http::kHeaderFieldsTooLarge)
STLREFINE_NAMED_PROBLEM(server_error, http::kInternalServerError)
STLREFINE_NAMED_PROBLEM(service_unavailable, http::kServiceUnavailable)
STLREFINE_NAMED_PROBLEM(too_many_requests, http::kTooManyRequests)
STLREFINE_NAMED_PROBLEM(gateway_timeout, http::kGatewayTimeout)
STLREFINE_NAMED_PROBLEM(insufficient_storage, http::kInsufficientStorage)
#undef STLREFINE_NAMED_PROBLEM

Problem internal_error() {
  return make_problem(http::kInternalServerError, "internal", "an internal error occurred");
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
