// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <functional>
#include <string_view>

namespace stlrefine {

//! Progress sink: fraction in [0, 1] and a short stage name ("level 2/3"). One progress
//! mechanism for refine (core/refine.h) and slice (slicer/slice.h).
using ProgressFn = std::function<void(double fraction, std::string_view stage)>;

}  // namespace stlrefine
