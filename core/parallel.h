// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <atomic>
#include <cstddef>

#include "core/error.h"

namespace stlrefine {

namespace detail {
inline thread_local const std::atomic<bool>* current_cancel_flag = nullptr;
}

//! While alive, parallel loops started from this thread stop early when `cancel` is raised
//! and then throw Error(Cancelled), so a cancelled request frees its cores within one chunk
//! of work, not at the end of a level.
class CancelScope {
 public:
  explicit CancelScope(const std::atomic<bool>* cancel) : previous_(detail::current_cancel_flag) {
    detail::current_cancel_flag = cancel;
  }
  ~CancelScope() { detail::current_cancel_flag = previous_; }
  CancelScope(const CancelScope&) = delete;
  CancelScope& operator=(const CancelScope&) = delete;

 private:
  const std::atomic<bool>* previous_;
};

//! Runs fn(begin, end) over consecutive chunks covering [0, n) on the TBB pool (the
//! caller's task arena decides how many threads), for loops that set up per-chunk state.
//! Small ranges run inline as one chunk: spawning costs more than it saves.
//! Under a CancelScope a raised flag skips the remaining chunks and throws
//! Error(Cancelled) here, in the calling thread.
template <class Fn>
void parallel_for_each_range(std::size_t n, Fn&& fn) {
  constexpr std::size_t kGrain = 4096;
  if (n < kGrain) {
    fn(std::size_t{0}, n);
    return;
  }
  const std::atomic<bool>* cancel = detail::current_cancel_flag;
  auto cancelled = [cancel] { return cancel && cancel->load(std::memory_order_relaxed); };
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, kGrain),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      if (cancelled()) return;
                      fn(r.begin(), r.end());
                    });
  if (cancelled()) throw Error(ErrorCode::Cancelled, "cancelled", "cancelled");
}

//! Runs fn(i) for i in [0, n), chunked and cancelled as parallel_for_each_range.
template <class Fn>
void parallel_for_each_index(std::size_t n, Fn&& fn) {
  parallel_for_each_range(n, [&](std::size_t begin, std::size_t end) {
    for (std::size_t i = begin; i != end; ++i) fn(i);
  });
}

}  // namespace stlrefine
