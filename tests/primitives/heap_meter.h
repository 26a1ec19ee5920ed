// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <cstdint>

namespace stlrefine::test {

//! Bytes the global operator new of this binary has handed out and not taken back.
std::uint64_t heap_live_bytes();
//! Sets the peak to the live bytes now and returns them.
std::uint64_t heap_reset_peak();
//! The most live bytes since the last reset.
std::uint64_t heap_peak_bytes();

}  // namespace stlrefine::test
