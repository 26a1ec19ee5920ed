// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/job_progress.h"

#include <algorithm>

namespace stlrefine::server {

namespace {

// Relative cost per unit of each stage, from stage timelines of fandisk jobs (butterfly,
// loop, lsf, 2-4 levels, sliced at 0.02-0.05 mm or not: bench/results-issue19-s4-jobs.md):
// reading and preparing an input face costs about what making one output face does; the
// deviation post-pass (when it runs) a little more than the refinement; slicing is per
// output face and per contour point; writing per output face.
constexpr double kIngestPerInputFace = 3;
constexpr double kRefinePerOutputFace = 3;
constexpr double kPostPassPerOutputFace = 4;
constexpr double kSlicePerOutputFace = 1;
constexpr double kSlicePerPoint = 2;
constexpr double kWritePerOutputFace = 2.5;
// Held back until the job is done: its final rename and record are not free either.
constexpr double kBeforeDone = 0.995;

}  // namespace

JobProgress::JobProgress(const api::RefinePlan& plan) {
  const double in = static_cast<double>(std::max<std::uint64_t>(plan.shape.faces, 1));
  const double out = static_cast<double>(std::max<std::uint64_t>(plan.predicted_faces, 1));
  weight_[0] = kIngestPerInputFace * in;
  weight_[1] = kRefinePerOutputFace * out;
  weight_[2] = plan.request.primitives.post_pass() ? kPostPassPerOutputFace * out : 0;
  weight_[3] = plan.request.slice
                   ? kSlicePerOutputFace * out +
                         kSlicePerPoint * static_cast<double>(plan.memory.contour_points)
                   : 0;
  weight_[4] = kWritePerOutputFace * out;
  double sum = 0;
  for (const double w : weight_) sum += w;
  for (double& w : weight_) w /= sum;
}

void JobProgress::set(Stage stage, double within, std::string label) {
  const auto s = static_cast<int>(stage);
  double before = 0;
  for (int i = 0; i < s; ++i) before += weight_[i];
  const double f = before + weight_[s] * std::clamp(within, 0.0, 1.0);
  // Never backwards: a stage's estimate may be off, the reading stays put until it catches up.
  fraction_ = std::clamp(std::max(fraction_, f), 0.0, kBeforeDone);
  stage_ = std::move(label);
}

void JobProgress::enter(Stage stage) {
  static constexpr const char* kNames[] = {"ingest", "refining", "post-pass", "slicing", "writing"};
  set(stage, 0, kNames[static_cast<int>(stage)]);
}

void JobProgress::on_core(double fraction, std::string_view core_stage) {
  if (core_stage == "slice") return set(Stage::Slice, fraction, "slicing");
  // refine() ends with 1 "done": the refinement is over, the post-pass comes next.
  // A multi-object 3MF refines its objects one after another and scales each one's fraction
  // to its share ((i + f) / n): an object's "done" below 1 is only that object's end, and the
  // next object's levels carry on from there.
  if (core_stage == "done" && fraction < 1) return set(Stage::Refine, fraction, "refining");
  if (core_stage == "done") return set(Stage::PostPass, 0, "post-pass");
  set(Stage::Refine, fraction, std::string(core_stage));  // "level 2/3", "adaptive level 1/4"
}

}  // namespace stlrefine::server
