// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Admission: what a planned computation goes through before any work, and how a refusal of
// its memory while it runs is answered. The one sequence the synchronous routes
// (compute_routes.cpp) and the job runner (job_runner.cpp) share; they differ only in how they wait
// for memory (`reserve`) and in their busy answer (`busy`).

#include <cstdint>
#include <functional>
#include <optional>

#include "api/memory_model.h"
#include "api/plan.h"
#include "api/problem.h"
#include "core/refine.h"

namespace stlrefine::server {

//! Reserves `bytes` (waiting as its caller wants); false when they did not come.
using ReserveFn = std::function<bool(std::uint64_t bytes)>;
//! The 503 of a request that needs `bytes` while other work holds the memory budget.
using BusyFn = std::function<api::Problem(std::uint64_t bytes)>;

//! Before any work, in this order: a refinement's face budget on its body's facets
//! (api::refuse_over_face_budget: throws FaceBudgetError, whose 422 problem_from_error
//! makes), the predicted peak against what one request may ever hold (`capacity`: the 422
//! of api::memory_budget_problem), then the reservation of that peak (`reserve`; refused:
//! busy(peak)). Nullopt: admitted, the peak reserved.
std::optional<api::Problem> admit(const api::RefinePlan& plan, std::uint64_t capacity,
                                  const ReserveFn& reserve, const BusyFn& busy);
//! admit for a plan without a face budget (slice, info): its predicted memory.
std::optional<api::Problem> admit(const api::MemoryEstimate& predicted, std::uint64_t capacity,
                                  const ReserveFn& reserve, const BusyFn& busy);

//! The answer to a computation its MemoryGrowFn stopped: above what one request may ever
//! hold, the 422 naming the level parameter; else it did not fit next to the other work:
//! busy(needed), retry later.
api::Problem memory_problem(const MemoryBudgetError& error, std::uint64_t capacity,
                            const BusyFn& busy);

}  // namespace stlrefine::server
