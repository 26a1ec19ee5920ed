// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cstddef>

namespace stlrefine {

//! Runs fn(i) for i in [0, n) on the TBB pool (the caller's task arena decides how many
//! threads). Small ranges run inline: spawning costs more than it saves.
template <class Fn>
void parallel_for_each_index(std::size_t n, Fn&& fn) {
  constexpr std::size_t kGrain = 4096;
  if (n < kGrain) {
    for (std::size_t i = 0; i < n; ++i) fn(i);
    return;
  }
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, kGrain),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t i = r.begin(); i != r.end(); ++i) fn(i);
                    });
}

}  // namespace stlrefine
