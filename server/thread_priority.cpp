// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/thread_priority.h"

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>

namespace stlrefine::server {

namespace {

id_t this_thread_id() {
  return static_cast<id_t>(::syscall(SYS_gettid));
}

}  // namespace

int thread_nice() {
  errno = 0;
  const int nice = ::getpriority(PRIO_PROCESS, this_thread_id());
  return errno == 0 ? nice : 0;
}

bool lower_thread_priority(int increment) {
  if (increment <= 0) return true;
  // On Linux PRIO_PROCESS with a thread id sets that thread's nice value alone.
  const int target = std::min(19, thread_nice() + increment);
  return ::setpriority(PRIO_PROCESS, this_thread_id(), target) == 0;
}

}  // namespace stlrefine::server
