// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/compute_slots.h"

namespace stlrefine::server {

ComputeSlots::Lease& ComputeSlots::Lease::operator=(Lease&& other) noexcept {
  if (this != &other) {
    release();
    slots_ = other.slots_;
    other.slots_ = nullptr;
  }
  return *this;
}

void ComputeSlots::Lease::release() {
  if (slots_) slots_->give_back();
  slots_ = nullptr;
}

std::optional<ComputeSlots::Lease> ComputeSlots::try_acquire() {
  std::lock_guard lock(mutex_);
  if (free_ == 0) return std::nullopt;
  --free_;
  return Lease(this);
}

std::size_t ComputeSlots::available() const {
  std::lock_guard lock(mutex_);
  return free_;
}

void ComputeSlots::give_back() {
  std::lock_guard lock(mutex_);
  ++free_;
}

}  // namespace stlrefine::server
