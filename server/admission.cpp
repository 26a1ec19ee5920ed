// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/admission.h"

#include "api/pipeline.h"

namespace stlrefine::server {

std::optional<api::Problem> admit(const api::RefinePlan& plan, std::uint64_t capacity,
                                  const ReserveFn& reserve, const BusyFn& busy) {
  // The face budget first: it is the request's own limit, with its own 422.
  api::refuse_over_face_budget(plan);
  return admit(plan.memory, capacity, reserve, busy);
}

std::optional<api::Problem> admit(const api::MemoryEstimate& predicted, std::uint64_t capacity,
                                  const ReserveFn& reserve, const BusyFn& busy) {
  if (predicted.peak_bytes > capacity) return api::memory_budget_problem(predicted, capacity);
  if (!reserve(predicted.peak_bytes)) return busy(predicted.peak_bytes);
  return std::nullopt;
}

api::Problem memory_problem(const MemoryBudgetError& error, std::uint64_t capacity,
                            const BusyFn& busy) {
  if (error.needed_bytes() > capacity) return api::memory_budget_problem(error, capacity);
  return busy(error.needed_bytes());
}

}  // namespace stlrefine::server
