// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/compute_slots.h"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>
#include <vector>

namespace stlrefine::server {
namespace {

TEST(ComputeSlots, NeverHandsOutMoreThanItHas) {
  ComputeSlots slots(2);
  auto a = slots.try_acquire();
  auto b = slots.try_acquire();
  ASSERT_TRUE(a && b);
  EXPECT_FALSE(slots.try_acquire());
  EXPECT_EQ(slots.available(), 0u);
  a.reset();
  EXPECT_EQ(slots.available(), 1u);
  EXPECT_TRUE(slots.try_acquire());  // a temporary lease, released at once
  EXPECT_EQ(slots.available(), 1u);
}

TEST(ComputeSlots, LeasesMoveAndReleaseOnce) {
  ComputeSlots slots(1);
  std::optional<ComputeSlots::Lease> a = slots.try_acquire();
  ASSERT_TRUE(a);
  ComputeSlots::Lease moved = std::move(*a);
  a.reset();  // the moved-from lease gives nothing back
  EXPECT_EQ(slots.available(), 0u);
  moved.release();
  moved.release();
  EXPECT_EQ(slots.available(), 1u);
}

TEST(ComputeSlots, ConcurrentHoldersStayWithinCapacity) {
  ComputeSlots slots(3);
  std::atomic<int> inside{0}, peak{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < 8; ++t) {
    threads.emplace_back([&] {
      for (int i = 0; i < 2000; ++i) {
        if (auto lease = slots.try_acquire()) {
          const int now = ++inside;
          int seen = peak.load();
          while (now > seen && !peak.compare_exchange_weak(seen, now)) {
          }
          --inside;
        }
      }
    });
  }
  for (auto& t : threads) t.join();
  EXPECT_LE(peak.load(), 3);
  EXPECT_EQ(slots.available(), 3u);
}

}  // namespace
}  // namespace stlrefine::server
