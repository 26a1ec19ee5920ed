// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

namespace stlrefine::server {

//! Raises the calling thread's nice value by `increment` (capped at 19); 0 does nothing.
//! Threads started from it inherit the value, so the thread pool a computing thread starts
//! (TBB's workers) runs at the same priority. An unprivileged thread cannot lower it again.
//! Returns false when the kernel refused.
bool lower_thread_priority(int increment);

//! The calling thread's nice value.
int thread_nice();

}  // namespace stlrefine::server
