// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
// What a client sees of a job: its JSON, the problems it ends with, the space it needs.
#include <cmath>
#include <cstdio>
#include <limits>

#include "server/job_parts.h"
#include "server/job_record.h"

namespace stlrefine::server {

namespace fs = std::filesystem;
using namespace job_files;

api::Problem deadline_problem(std::chrono::milliseconds deadline) {
  const double seconds = std::chrono::duration<double>(deadline).count();
  char text[32];
  std::snprintf(text, sizeof text, "%g", seconds);
  api::Problem p = api::gateway_timeout(
      "deadline-exceeded",
      std::string("deadline exceeded: the computation ran longer than this server's request "
                  "deadline of ") +
          text + " s and was cancelled");
  p.extensions["reason"] = "deadline_exceeded";
  p.extensions["deadline_seconds"] = seconds;
  return p;
}

const char* to_string(JobState state) {
  switch (state) {
    case JobState::Queued:
      return "queued";
    case JobState::Running:
      return "running";
    case JobState::Done:
      return "done";
    case JobState::Failed:
      return "failed";
    case JobState::Cancelled:
      return "cancelled";
  }
  return "unknown";
}

nlohmann::ordered_json eta_seconds(const JobView& job) {
  if (job.state == JobState::Done) return 0;
  const bool has_started = job.started.time_since_epoch().count() != 0;
  if (job.state != JobState::Running || !has_started) return nullptr;
  // The rate so far, once there is one: a second of running and 2% of the work (before
  // that, the first stage's start-up dominates and the figure jumps around).
  const double elapsed = std::chrono::duration<double>(Clock::now() - job.started).count();
  if (elapsed < 1 || job.progress < 0.02) return nullptr;
  return std::round(elapsed * (1 - job.progress) / job.progress * 10) / 10;
}

nlohmann::ordered_json job_json(const JobView& job) {
  nlohmann::ordered_json j;
  const std::string self = "/v1/jobs/" + job.id;
  j["id"] = job.id;
  j["state"] = to_string(job.state);
  if (job.expired) j["expired"] = true;
  j["progress"] = job.progress;
  j["stage"] = job.stage;
  j["eta_seconds"] = eta_seconds(job);
  j["scheme"] = job.scheme;
  j["parameters"] = job.query;
  if (!job.name.empty()) j["name"] = job.name;
  if (!job.callback_url.empty()) j["callback_url"] = job.callback_url;
  if (!job.worker.empty()) j["worker"] = job.worker;  // queue mode: the replica running it
  nlohmann::ordered_json t;
  t["created"] = iso8601(job.created);
  const bool has_started = job.started.time_since_epoch().count() != 0;
  const bool has_finished = job.finished.time_since_epoch().count() != 0;
  if (has_started) {
    t["started"] = iso8601(job.started);
    t["queued_seconds"] = std::chrono::duration<double>(job.started - job.created).count();
  }
  if (has_finished) {
    t["finished"] = iso8601(job.finished);
    if (has_started)
      t["run_seconds"] = std::chrono::duration<double>(job.finished - job.started).count();
  }
  j["timings"] = t;
  if (!job.report.empty()) j["report"] = job.report;
  if (job.problem) j["problem"] = *job.problem;
  nlohmann::ordered_json links;
  links["self"] = self;
  for (const std::string& name : job.results) {
    if (part_file_name(name)) continue;                      // under `parts`
    const std::string key = name.substr(0, name.find('.'));  // result, contours, report
    links[key] = self + "/" + name;
  }
  j["links"] = links;
  // A zip's parts, each with its files (links.result is then result.zip, all of them).
  if (job.report.contains("parts")) j["parts"] = parts_json(job.report, self);
  return j;
}

api::Problem no_space_problem(const SubmitResult& refused) {
  api::Problem p = api::insufficient_storage(
      "insufficient-storage",
      "not enough free space for this job's input and results on the server's data "
      "directory; retry later");
  p.extensions["reason"] = "no_space";
  p.extensions["needed_bytes"] = refused.needed_bytes;
  p.extensions["free_bytes"] = refused.free_bytes;
  return p;
}

std::uint64_t predicted_result_bytes(const api::RefineRequest& request,
                                     const api::MemoryEstimate& predicted) {
  // A binary facet is 50 bytes; an ASCII one ("facet normal ... endfacet" with %e numbers)
  // under 300. Contour points: at most 48 bytes in the text formats. The report: 64 KiB.
  const std::uint64_t facet = request.output_format == StlFormat::Binary ? 50 : 300;
  std::uint64_t bytes = saturating_add(
      84, facet > 0 && predicted.output_faces > std::numeric_limits<std::uint64_t>::max() / facet
              ? std::numeric_limits<std::uint64_t>::max()
              : facet * predicted.output_faces);
  if (request.slice)
    bytes = saturating_add(bytes,
                           predicted.contour_points > std::numeric_limits<std::uint64_t>::max() / 48
                               ? std::numeric_limits<std::uint64_t>::max()
                               : 48 * predicted.contour_points);
  return saturating_add(bytes, std::uint64_t{64} << 10);
}

}  // namespace stlrefine::server
