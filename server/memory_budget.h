// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <cstdint>
#include <mutex>
#include <optional>
#include <string_view>

namespace stlrefine::server {

//! "512M", "2G", "1.5GiB", "64k", "800000000": a byte count with an optional binary suffix
//! (K, M, G, T = 2^10 .. 2^40, any case, optionally followed by "i" and/or "B"). A bare
//! number is bytes. \throw std::invalid_argument naming the text.
std::uint64_t parse_byte_size(std::string_view text);

//! Half of the memory this process may use: the smaller of the physical RAM and the cgroup
//! limit (v2 memory.max, v1 memory.limit_in_bytes) when there is one.
std::uint64_t default_memory_budget();

//! The daemon's memory budget: every computing request (and the answer it holds until it
//! is sent) reserves its predicted peak (api/memory_model.h) here first. A prediction above
//! capacity() can never run (422); one that fits alone but not next to the reservations
//! already made waits (jobs) or gets 503 (synchronous requests). Never blocks.
class MemoryBudget {
 public:
  //! Holds bytes of the budget until destroyed.
  class Reservation {
   public:
    Reservation(Reservation&& other) noexcept : budget_(other.budget_), bytes_(other.bytes_) {
      other.budget_ = nullptr;
      other.bytes_ = 0;
    }
    Reservation& operator=(Reservation&& other) noexcept;
    Reservation(const Reservation&) = delete;
    Reservation& operator=(const Reservation&) = delete;
    ~Reservation() { release(); }

    std::uint64_t bytes() const { return bytes_; }
    //! Grows the reservation to `total` bytes when that fits next to the others; true when
    //! it holds at least `total` afterwards.
    bool grow_to(std::uint64_t total);
    //! Gives back what is above `total` (no-op when it holds less).
    void shrink_to(std::uint64_t total);
    void release();

   private:
    friend class MemoryBudget;
    Reservation(MemoryBudget* budget, std::uint64_t bytes) : budget_(budget), bytes_(bytes) {}
    MemoryBudget* budget_;
    std::uint64_t bytes_;
  };

  //! `budget`: what the whole daemon may use; `reserve`: what the idle daemon needs for
  //! itself (code, thread stacks, connection buffers), never handed to requests.
  //! \pre budget > reserve
  MemoryBudget(std::uint64_t budget, std::uint64_t reserve);
  MemoryBudget(const MemoryBudget&) = delete;
  MemoryBudget& operator=(const MemoryBudget&) = delete;

  //! A reservation of `bytes`, or nothing when it does not fit next to the others now.
  std::optional<Reservation> try_reserve(std::uint64_t bytes);
  //! The most one request may reserve: budget - reserve.
  std::uint64_t capacity() const { return capacity_; }
  std::uint64_t budget() const { return budget_; }
  std::uint64_t reserved() const;

 private:
  bool take(std::uint64_t bytes);
  void give_back(std::uint64_t bytes);

  const std::uint64_t budget_;
  const std::uint64_t capacity_;
  mutable std::mutex mutex_;
  std::uint64_t used_ = 0;
};

}  // namespace stlrefine::server
