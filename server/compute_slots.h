// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <cstddef>
#include <mutex>
#include <optional>

namespace stlrefine::server {

//! A counting semaphore that never waits: the daemon admits as many compute requests as
//! it has slots and answers 503 to the rest at once, instead of queueing without bound.
class ComputeSlots {
 public:
  //! Holds one slot until destroyed.
  class Lease {
   public:
    Lease(Lease&& other) noexcept : slots_(other.slots_) { other.slots_ = nullptr; }
    Lease& operator=(Lease&& other) noexcept;
    Lease(const Lease&) = delete;
    Lease& operator=(const Lease&) = delete;
    ~Lease() { release(); }
    void release();

   private:
    friend class ComputeSlots;
    explicit Lease(ComputeSlots* slots) : slots_(slots) {}
    ComputeSlots* slots_;
  };

  //! \pre capacity >= 1
  explicit ComputeSlots(std::size_t capacity) : capacity_(capacity), free_(capacity) {}
  ComputeSlots(const ComputeSlots&) = delete;
  ComputeSlots& operator=(const ComputeSlots&) = delete;

  //! A lease on a free slot, or nothing when every slot is taken.
  std::optional<Lease> try_acquire();
  std::size_t capacity() const { return capacity_; }
  std::size_t available() const;

 private:
  void give_back();

  const std::size_t capacity_;
  mutable std::mutex mutex_;
  std::size_t free_;
};

}  // namespace stlrefine::server
