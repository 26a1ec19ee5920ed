// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>

#include "core/error.h"

namespace stlrefine::api {

//! Media type of every error body (RFC 9457).
inline constexpr const char* kProblemContentType = "application/problem+json";
//! Problem `type` URIs are this prefix followed by the slug ("invalid-parameter", ...).
inline constexpr std::string_view kProblemTypePrefix = "urn:stlrefine:problem:";

//! The HTTP statuses the daemon answers with, named: server/ sets no status by number
//! (tests/server/status_map_test.cpp greps it).
namespace http {
inline constexpr int kOk = 200;
inline constexpr int kAccepted = 202;
inline constexpr int kNoContent = 204;
inline constexpr int kPartialContent = 206;
inline constexpr int kNotModified = 304;
inline constexpr int kBadRequest = 400;
inline constexpr int kUnauthorized = 401;
inline constexpr int kForbidden = 403;
inline constexpr int kNotFound = 404;
inline constexpr int kMethodNotAllowed = 405;
inline constexpr int kRequestTimeout = 408;
inline constexpr int kConflict = 409;
inline constexpr int kGone = 410;
inline constexpr int kLengthRequired = 411;
inline constexpr int kContentTooLarge = 413;
inline constexpr int kUriTooLong = 414;
inline constexpr int kUnsupportedMediaType = 415;
inline constexpr int kRangeNotSatisfiable = 416;
inline constexpr int kExpectationFailed = 417;
inline constexpr int kUnprocessableContent = 422;
inline constexpr int kTooManyRequests = 429;
inline constexpr int kHeaderFieldsTooLarge = 431;
//! Not sent: what the access log records for a client that closed before the answer.
inline constexpr int kClientClosed = 499;
inline constexpr int kInternalServerError = 500;
inline constexpr int kServiceUnavailable = 503;
inline constexpr int kGatewayTimeout = 504;
inline constexpr int kInsufficientStorage = 507;
}  // namespace http

//! The status line's RFC 9110 reason phrase ("Content Too Large"); from the same table as
//! the problem titles ("Content too large").
const char* reason_phrase(int status);

//! An RFC 9457 problem: the one error shape of the daemon, also what the CLI prints.
struct Problem {
  int status = 500;
  std::string slug = "internal";             //!< `type` without kProblemTypePrefix
  std::string title;                         //!< short, fixed per slug
  std::string detail;                        //!< this occurrence, for humans
  std::string field;                         //!< the offending parameter, when there is one
  std::optional<std::uint64_t> byte_offset;  //!< where in a binary STL
  std::optional<std::uint64_t> line;         //!< where in an ASCII STL (1-based)
  //! Extension members: `reason` (the core's slug), `predicted_faces`, `max_faces`, ...
  nlohmann::ordered_json extensions = nlohmann::ordered_json::object();
};

//! The face budget failure with its numbers, so the 422 body can carry them.
class FaceBudgetError : public Error {
 public:
  FaceBudgetError(const Error& error, std::uint64_t predicted_faces, std::uint64_t max_faces)
      : Error(error), predicted_faces_(predicted_faces), max_faces_(max_faces) {}
  std::uint64_t predicted_faces() const { return predicted_faces_; }
  std::uint64_t max_faces() const { return max_faces_; }

 private:
  std::uint64_t predicted_faces_;
  std::uint64_t max_faces_;
};

//! The one ErrorCode -> HTTP status mapping: InvalidParameter 400; MalformedStl,
//! NotTriangleMesh, BudgetExceeded 422; Cancelled 503; Internal 500.
int http_status(ErrorCode code);

//! A problem for a core error. Internal errors get a generic detail: their text is for
//! the log, not for the client.
Problem problem_from_error(const Error& error);

//! A problem for a transport-level failure (404, 405, 411, 413, 415, 503, 500, ...).
//! The title is derived from the status.
Problem make_problem(int status, std::string slug, std::string detail);

//! Named problems, one per transport status (make_problem with that status): what server/
//! answers with instead of a number.
Problem bad_request(std::string slug, std::string detail);
Problem unauthorized(std::string slug, std::string detail);
Problem forbidden(std::string slug, std::string detail);
Problem not_found(std::string slug, std::string detail);
Problem method_not_allowed(std::string slug, std::string detail);
Problem request_timeout(std::string slug, std::string detail);
Problem conflict(std::string slug, std::string detail);
Problem gone(std::string slug, std::string detail);
Problem length_required(std::string slug, std::string detail);
Problem content_too_large(std::string slug, std::string detail);
Problem uri_too_long(std::string slug, std::string detail);
Problem unsupported_media_type(std::string slug, std::string detail);
Problem range_not_satisfiable(std::string slug, std::string detail);
Problem header_fields_too_large(std::string slug, std::string detail);
Problem server_error(std::string slug, std::string detail);
Problem service_unavailable(std::string slug, std::string detail);
Problem too_many_requests(std::string slug, std::string detail);
Problem gateway_timeout(std::string slug, std::string detail);
Problem insufficient_storage(std::string slug, std::string detail);
//! The 500 of a failure whose text is for the log only: "an internal error occurred".
Problem internal_error();

//! The RFC 9457 body: type, title, status, detail, then field / byte_offset / line when
//! known, then the extensions.
nlohmann::ordered_json to_json(const Problem& problem);

//! Compact, ASCII-only JSON text of to_json(problem).
std::string problem_body(const Problem& problem);

}  // namespace stlrefine::api
