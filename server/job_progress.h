// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// A job's progress as a client reads it: one fraction over all its stages (ingest, the
// refinement's levels, the deviation post-pass, slicing, writing the results), each
// weighted by the work predicted for it from the plan, and never going backwards. The core
// reports each stage's own fraction (a refinement ends with 1 "done", then slicing starts
// again from 0): mapped here, a poll never reads 1 before the job is done.

#include <string>
#include <string_view>

#include "api/plan.h"

namespace stlrefine::server {

class JobProgress {
 public:
  enum class Stage { Ingest, Refine, PostPass, Slice, Write };

  explicit JobProgress(const api::RefinePlan& plan);

  //! The core's callback (api::run_refine_to_mesh's ProgressFn): its stage-local fraction
  //! and stage name become the overall fraction and a stage a client can read.
  void on_core(double fraction, std::string_view core_stage);
  //! Enters `stage` at its start (Write once the computation returned).
  void enter(Stage stage);

  //! In [0, 1): 1 is only ever the done job's.
  double fraction() const { return fraction_; }
  //! "ingest", "level 2/3", "adaptive level 1/4", "post-pass", "slicing", "writing";
  //! never "done" (the job's state says that).
  const std::string& stage() const { return stage_; }

 private:
  void set(Stage stage, double within, std::string label);

  double weight_[5] = {};  // per Stage, normalised to a sum of 1
  double fraction_ = 0;
  std::string stage_ = "ingest";
};

}  // namespace stlrefine::server
