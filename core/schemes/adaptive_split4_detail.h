// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// Shared by adaptive_split4.cpp and adaptive_split4_uniform.cpp. Internal to core/schemes.
#pragma once

#include <cstdint>

#include "core/schemes/split4_host.h"

namespace stlrefine::adaptive_split4_detail {

//! What the marking of `level` allocates besides the level at most: the candidate points,
//! the stencil's scratch, the plane rule's and the fold guard's flags and the marks (the
//! guard's work arrays are reserved by the guard itself).
std::uint64_t marking_bytes(const Level& level, const Split4Stencil& stencil);

}  // namespace stlrefine::adaptive_split4_detail
