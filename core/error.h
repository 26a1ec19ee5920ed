// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>

namespace stlrefine {

//! What kind of failure an Error reports; server/api maps each to one HTTP status.
enum class ErrorCode {
  InvalidParameter,  //!< a parameter is out of range or malformed (HTTP 400)
  MalformedStl,      //!< the bytes are not a readable STL (HTTP 422)
  NotTriangleMesh,   //!< readable, but nothing we can refine (e.g. every facet degenerate) (422)
  BudgetExceeded,    //!< the request would exceed a face or memory budget (422)
  //! valid parameters that make nothing from this part, e.g. a slice without a layer (422)
  NothingToMake,
  Cancelled,  //!< the caller's cancel flag was raised
  Internal,   //!< a broken invariant: a bug, never the user's fault (500)
};

const char* to_string(ErrorCode code);

//! The one exception type core/ and slicer/ throw. `reason` is a stable slug
//! ("truncated", "count_mismatch", "non_finite", ...), `field` names the offending
//! parameter, and a byte offset or line locates the problem in an input file.
class Error : public std::runtime_error {
 public:
  Error(ErrorCode code, std::string reason, const std::string& message)
      : std::runtime_error(message), code_(code), reason_(std::move(reason)) {}

  ErrorCode code() const { return code_; }
  const std::string& reason() const { return reason_; }
  const std::string& field() const { return field_; }
  std::optional<std::uint64_t> byte_offset() const { return byte_offset_; }
  std::optional<std::uint64_t> line() const { return line_; }

  Error& with_field(std::string field) {
    field_ = std::move(field);
    return *this;
  }
  Error& at_byte(std::uint64_t offset) {
    byte_offset_ = offset;
    return *this;
  }
  Error& at_line(std::uint64_t line) {
    line_ = line;
    return *this;
  }

 private:
  ErrorCode code_;
  std::string reason_;
  std::string field_;
  std::optional<std::uint64_t> byte_offset_;
  std::optional<std::uint64_t> line_;
};

//! Throws InvalidParameter naming `field` unless lo <= value <= hi.
template <class T>
void require_in_range(const char* field, T value, T lo, T hi) {
  if (!(value >= lo && value <= hi)) {
    throw Error(ErrorCode::InvalidParameter, "out_of_range",
                std::string(field) + " = " + std::to_string(value) + " is outside [" +
                    std::to_string(lo) + ", " + std::to_string(hi) + "]")
        .with_field(field);
  }
}

}  // namespace stlrefine
