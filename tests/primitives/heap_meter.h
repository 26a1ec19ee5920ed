// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <cstdint>

#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#define STLREFINE_HEAP_METER_OFF 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__)
#define STLREFINE_HEAP_METER_OFF 1
#endif

namespace stlrefine::test {

//! False under AddressSanitizer: ASan owns operator new / delete (its redzones, quarantine and
//! allocation-mismatch checks), so this binary does not replace them there and the heap is not
//! counted; the memory tests skip and the Release run is their check.
constexpr bool heap_meter_active() {
#ifdef STLREFINE_HEAP_METER_OFF
  return false;
#else
  return true;
#endif
}

//! Bytes the global operator new of this binary has handed out and not taken back.
std::uint64_t heap_live_bytes();
//! Sets the peak to the live bytes now and returns them.
std::uint64_t heap_reset_peak();
//! The most live bytes since the last reset.
std::uint64_t heap_peak_bytes();

}  // namespace stlrefine::test
