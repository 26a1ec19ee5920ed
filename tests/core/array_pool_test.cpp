// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// The array pool behind BigVector's mid-size arrays: size classes, reuse of returned
// blocks, no overlap, the limit (then operator new), foreign pointers refused, threads.

#include "core/mesh/array_pool.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <numeric>
#include <random>
#include <thread>
#include <vector>

#include "core/mesh/big_vector.h"

#if defined(__SANITIZE_ADDRESS__)
#define POOL_TEST_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define POOL_TEST_ASAN 1
#endif
#endif

namespace stlrefine {
namespace {

using array_pool::kMinBytes;
using array_pool::kSlabBytes;

struct Block {
  std::uint32_t* data;
  std::size_t bytes;
};

void fill(const Block& b, std::uint32_t tag) {
  for (std::size_t i = 0; i < b.bytes / 4; ++i) b.data[i] = tag ^ std::uint32_t(i);
}
bool holds(const Block& b, std::uint32_t tag) {
  for (std::size_t i = 0; i < b.bytes / 4; ++i)
    if (b.data[i] != (tag ^ std::uint32_t(i))) return false;
  return true;
}

TEST(ArrayPool, SizeClassesCoverTheRangeWithAtMostHalfOrAPageMore) {
  EXPECT_EQ(array_pool::block_bytes(kMinBytes - 1), 0u);
  EXPECT_EQ(array_pool::block_bytes(kSlabBytes), 0u);
  EXPECT_EQ(array_pool::block_bytes(kMinBytes), kMinBytes);
  EXPECT_EQ(array_pool::block_bytes(kMinBytes + 1), 8u << 10);
  EXPECT_EQ(array_pool::block_bytes(129u << 10), 192u << 10);
  EXPECT_EQ(array_pool::block_bytes(kSlabBytes - 1), kSlabBytes);
  EXPECT_EQ(array_pool::allocate(kMinBytes - 1), nullptr);
  EXPECT_EQ(array_pool::allocate(kSlabBytes), nullptr);
  for (std::size_t bytes = kMinBytes; bytes < kSlabBytes; bytes += 1021) {
    const std::size_t block = array_pool::block_bytes(bytes);
    ASSERT_GE(block, bytes);
    ASSERT_LE(block, std::max(bytes + bytes / 2, bytes + 4096)) << bytes;
    ASSERT_EQ(block % 4096, 0u);
  }
}

TEST(ArrayPool, AReturnedBlockIsReusedForTheSameClass) {
  void* p = array_pool::allocate(100'000);
  ASSERT_NE(p, nullptr);
  const std::size_t in_use = array_pool::stats().blocks_in_use;
  EXPECT_TRUE(array_pool::deallocate(p, 100'000));
  EXPECT_EQ(array_pool::stats().blocks_in_use, in_use - 1);
  void* q = array_pool::allocate(120'000);  // same class (128 KiB)
  EXPECT_EQ(q, p);
  EXPECT_TRUE(array_pool::deallocate(q, 120'000));
}

TEST(ArrayPool, BlocksAreAlignedDisjointAndKeepTheirContents) {
  std::mt19937 rng(7);
  std::uniform_int_distribution<std::size_t> size(kMinBytes, 700'000);
  std::vector<Block> blocks;
  std::size_t total = 0;
  while (total < 24u << 20) {
    const std::size_t bytes = size(rng) & ~std::size_t{3};
    auto* p = static_cast<std::uint32_t*>(array_pool::allocate(bytes));
    ASSERT_NE(p, nullptr);
    EXPECT_EQ(reinterpret_cast<std::uintptr_t>(p) % 4096, 0u);
    blocks.push_back({p, bytes});
    fill(blocks.back(), std::uint32_t(blocks.size()));
    total += bytes;
  }
  for (std::size_t i = 0; i < blocks.size(); ++i)
    ASSERT_TRUE(holds(blocks[i], std::uint32_t(i + 1)));
  // Return every other block, take new ones (reusing them), and check nothing moved.
  for (std::size_t i = 0; i < blocks.size(); i += 2) {
    ASSERT_TRUE(array_pool::deallocate(blocks[i].data, blocks[i].bytes));
    blocks[i].data = static_cast<std::uint32_t*>(array_pool::allocate(blocks[i].bytes));
    ASSERT_NE(blocks[i].data, nullptr);
    fill(blocks[i], std::uint32_t(1000 + i));
  }
  for (std::size_t i = 0; i < blocks.size(); ++i)
    ASSERT_TRUE(holds(blocks[i], std::uint32_t(i % 2 == 0 ? 1000 + i : i + 1))) << i;
  for (const Block& b : blocks) ASSERT_TRUE(array_pool::deallocate(b.data, b.bytes));
}

TEST(ArrayPool, PointersFromElsewhereAreNotTaken) {
  void* heap = std::malloc(100'000);
  EXPECT_FALSE(array_pool::deallocate(heap, 100'000));
  std::free(heap);
  EXPECT_FALSE(array_pool::deallocate(nullptr, 100'000));
  int on_stack = 0;
  EXPECT_FALSE(array_pool::deallocate(&on_stack, 100'000));
}

TEST(ArrayPool, AtItsLimitThePoolSaysNoAndBigVectorsFallBackToOperatorNew) {
  const std::size_t old_limit = array_pool::limit_bytes();
  array_pool::set_limit_bytes((array_pool::stats().slabs + 1) * kSlabBytes);
  std::vector<void*> whole_slabs;
  while (void* p = array_pool::allocate(kSlabBytes - 1)) {
    whole_slabs.push_back(p);
    ASSERT_LE(whole_slabs.size(), 64u);  // the old slabs' free lists hold a bounded number
  }
  const std::size_t slabs = array_pool::stats().slabs;
  BigVector<std::uint32_t> array(300'000);  // 1.2 MB: a pool size, served by operator new
  std::iota(array.begin(), array.end(), 0u);
  EXPECT_EQ(array[299'999], 299'999u);
  EXPECT_EQ(array_pool::stats().slabs, slabs);
  array = {};
  for (void* p : whole_slabs) EXPECT_TRUE(array_pool::deallocate(p, kSlabBytes - 1));
  array_pool::set_limit_bytes(old_limit);
}

TEST(ArrayPool, BigVectorsOfPoolSizeUseThePoolAndGiveTheirBlocksBack) {
  const std::size_t before = array_pool::stats().blocks_in_use;
  {
    BigVector<double> a(20'000);  // 160 KB
    BigVector<double> b(400);     // 3.2 KB: malloc
    EXPECT_EQ(array_pool::stats().blocks_in_use, before + 1);
    a.assign(a.size(), 1.5);
    EXPECT_EQ(a.back(), 1.5);
  }
  EXPECT_EQ(array_pool::stats().blocks_in_use, before);
}

TEST(ArrayPool, ThreadsTakingAndReturningBlocksNeverShareOne) {
  auto worker = [](unsigned seed, bool* ok) {
    std::mt19937 rng(seed);
    std::uniform_int_distribution<std::size_t> size(kMinBytes, 400'000);
    std::vector<Block> mine;
    for (int round = 0; round < 400; ++round) {
      if (mine.size() < 6) {
        const std::size_t bytes = size(rng) & ~std::size_t{3};
        auto* p = static_cast<std::uint32_t*>(array_pool::allocate(bytes));
        if (!p) continue;  // at the limit: allowed
        mine.push_back({p, bytes});
        fill(mine.back(), seed * 1000 + std::uint32_t(mine.size()));
      } else {
        for (std::size_t i = 0; i < mine.size(); ++i)
          if (!holds(mine[i], seed * 1000 + std::uint32_t(i + 1))) *ok = false;
        for (const Block& b : mine) array_pool::deallocate(b.data, b.bytes);
        mine.clear();
      }
    }
    for (const Block& b : mine) array_pool::deallocate(b.data, b.bytes);
  };
  constexpr int kThreads = 4;
  bool ok[kThreads] = {true, true, true, true};
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) threads.emplace_back(worker, unsigned(t + 1), &ok[t]);
  for (auto& t : threads) t.join();
  for (int t = 0; t < kThreads; ++t) EXPECT_TRUE(ok[t]) << "thread " << t;
}

#ifdef POOL_TEST_ASAN
// The sanitizer build must still see overruns and use-after-free in pooled arrays.
TEST(ArrayPoolDeathTest, UnderAsanBytesPastTheRequestAndReturnedBlocksAreOffLimits) {
  auto* p = static_cast<char*>(array_pool::allocate(10'000));  // a 12 KiB block
  ASSERT_NE(p, nullptr);
  volatile char* v = p;
  v[9'999] = 1;
  EXPECT_DEATH(v[10'000] = 1, "use-after-poison");
  ASSERT_TRUE(array_pool::deallocate(p, 10'000));
  EXPECT_DEATH(v[0] = 1, "use-after-poison");
}
#endif

}  // namespace
}  // namespace stlrefine
