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

//! The RFC 9457 body: type, title, status, detail, then field / byte_offset / line when
//! known, then the extensions.
nlohmann::ordered_json to_json(const Problem& problem);

//! Compact, ASCII-only JSON text of to_json(problem).
std::string problem_body(const Problem& problem);

}  // namespace stlrefine::api
