// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/error.h"

namespace stlrefine {

const char* to_string(ErrorCode code) {
  switch (code) {
    case ErrorCode::InvalidParameter:
      return "invalid_parameter";
    case ErrorCode::MalformedStl:
      return "malformed_stl";
    case ErrorCode::NotTriangleMesh:
      return "not_triangle_mesh";
    case ErrorCode::BudgetExceeded:
      return "budget_exceeded";
    case ErrorCode::NothingToMake:
      return "nothing_to_make";
    case ErrorCode::Cancelled:
      return "cancelled";
    case ErrorCode::Internal:
      return "internal";
  }
  return "internal";
}

}  // namespace stlrefine
