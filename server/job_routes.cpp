// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/job_routes.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <set>
#include <span>

#include "api/archive.h"
#include "api/plan.h"
#include "core/error.h"
#include "server/http_upload.h"
#include "server/job_parts.h"
#include "server/memory_budget.h"
#include "slicer/writers.h"

namespace stlrefine::server {

namespace {

// Result files a job may have.
bool job_file_name(const std::string& name) {
  return name == "result.stl" || name == "result.3mf" || name == "result.zip" ||
         part_file_name(name) || name == "report.json" || name == "contours.json" ||
         name == "contours.svg" || name == "contours.cli";
}

api::Problem list_problem(const std::string& field, std::string detail) {
  api::Problem p = api::bad_request("invalid-parameter", std::move(detail));
  p.field = field;
  return p;
}

// A list cursor: the last job of a page as "<created_ms hex>-<id>". Opaque to clients; only
// what list_cursor() makes is read back.
std::string list_cursor(const JobView& job) {
  char text[24];
  std::snprintf(
      text, sizeof text, "%llx-",
      static_cast<unsigned long long>(
          std::chrono::duration_cast<std::chrono::milliseconds>(job.created.time_since_epoch())
              .count()));
  return text + job.id;
}

std::optional<JobStore::ListCursor> read_cursor(std::string_view text) {
  const std::size_t dash = text.find('-');
  if (dash == 0 || dash == std::string_view::npos || dash > 15 || text.size() != dash + 33)
    return std::nullopt;
  unsigned long long ms = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + dash, ms, 16);
  if (ec != std::errc() || end != text.data() + dash) return std::nullopt;
  const std::string_view id = text.substr(dash + 1);
  if (!std::all_of(id.begin(), id.end(),
                   [](char c) { return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'); }))
    return std::nullopt;
  return JobStore::ListCursor{static_cast<std::int64_t>(ms), std::string(id)};
}

}  // namespace

void serve_job_list(const RouteContext& ctx, const HttpRequest& req, HttpAnswer& res) {
  std::size_t limit = 20;
  std::optional<JobState> state;
  std::optional<JobStore::ListCursor> cursor;
  std::string state_text, cursor_text;
  try {
    std::set<std::string> seen;
    for (const auto& [name, value] : req.parameters()) {
      if (!seen.insert(name).second)
        return ctx.respond(
            res, list_problem(name, "parameter '" + shortened(name) + "' is given twice"));
      if (name == "limit") {
        unsigned long long n = 0;
        const auto [end, ec] = std::from_chars(value.data(), value.data() + value.size(), n);
        if (value.empty() || ec != std::errc() || end != value.data() + value.size() || n < 1 ||
            n > 100)
          return ctx.respond(res,
                             list_problem("limit", "limit must be an integer in [1, 100], not '" +
                                                       shortened(value) + "'"));
        limit = static_cast<std::size_t>(n);
      } else if (name == "state") {
        for (JobState s : {JobState::Queued, JobState::Running, JobState::Done, JobState::Failed,
                           JobState::Cancelled})
          if (value == to_string(s)) state = s;
        if (!state)
          return ctx.respond(
              res, list_problem("state",
                                "state must be queued, running, done, failed or cancelled, not '" +
                                    shortened(value) + "'"));
        state_text = value;
      } else if (name == "cursor") {
        cursor = read_cursor(value);
        if (!cursor)
          return ctx.respond(res,
                             list_problem("cursor", "cursor '" + shortened(value) +
                                                        "' is not one this server made (use the "
                                                        "`next` link of the page before)"));
        cursor_text = value;
      } else {
        return ctx.respond(res,
                           list_problem(name, "unknown parameter '" + shortened(name) +
                                                  "' (GET /v1/jobs takes limit, cursor, state)"));
      }
    }
  } catch (const Error& e) {
    return ctx.respond(res, api::problem_from_error(e));
  }
  bool more = false;
  const std::vector<JobView> jobs = ctx.jobs->list(ctx.tenant(req), state, cursor, limit, &more);
  nlohmann::ordered_json j;
  j["jobs"] = nlohmann::ordered_json::array();
  for (const JobView& job : jobs) j["jobs"].push_back(job_json(job));
  auto page = [&](const std::string& at) {
    std::string link = "/v1/jobs?limit=" + std::to_string(limit);
    if (state) link.append("&state=").append(state_text);
    if (!at.empty()) link.append("&cursor=").append(at);
    return link;
  };
  nlohmann::ordered_json links;
  links["self"] = page(cursor_text);
  if (more && !jobs.empty()) {
    j["next_cursor"] = list_cursor(jobs.back());
    links["next"] = page(list_cursor(jobs.back()));
  }
  j["links"] = links;
  res.set_content(j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n",
                  kJsonContentType);
}

void serve_job_submit(const RouteContext& ctx, const HttpRequest& req, api::RefinePlan parameters,
                      HttpAnswer& res) {
  Upload upload;
  if (std::optional<api::Problem> bad = read_upload(req, upload)) return ctx.respond(res, *bad);
  const std::string_view body = upload.bytes;
  // callback_url: refused now (syntax, allow-list, resolved addresses), not when it ends.
  std::string callback_url;
  try {
    int given = 0;
    for (auto& [name, value] : req.parameters())
      if (name == "callback_url") {
        callback_url = value;
        ++given;
      }
    if (given > 1) {
      api::Problem p = api::bad_request("invalid-parameter", "callback_url is given twice");
      p.field = "callback_url";
      return ctx.respond(res, p);
    }
  } catch (const Error& e) {
    return ctx.respond(res, api::problem_from_error(e));
  }
  if (!callback_url.empty())
    if (std::optional<api::Problem> refused =
            check_callback_url(ctx.jobs->config().callbacks, callback_url, nullptr))
      return ctx.respond(res, *refused);
  if (ctx.config.test_hook) ctx.config.test_hook("/v1/jobs");
  // The contours carry the file's name (SVG title, CLI $$LABEL, JSON name).
  if (parameters.request.slice) parameters.request.slice->writer.label = download_stem(upload.name);
  // Accept: model/3mf chooses 3MF when the query names no mesh_format, as on /v1/refine.
  if (!parameters.request.mesh_format_given && !parameters.request.slice &&
      req.header("Accept").find("model/3mf") != std::string::npos)
    parameters.request.mesh_format = MeshFormat::ThreeMf;
  try {
    // A job that could never get its memory is refused now, not when its turn comes.
    const auto bytes = std::span(reinterpret_cast<const std::uint8_t*>(body.data()), body.size());
    // A zip of mesh files is one job with one result per part (job_parts.h).
    // A 3MF of several objects refined to STL likewise, one part per object.
    std::uint64_t result_bytes = 0;
    // The inflated parts are held while the job is submitted: reserved first, beside the
    // body (503 while the budget is busy, 422 beyond it).
    api::ArchiveLimits limits = job_archive_limits(ctx.config.max_body_bytes);
    std::optional<MemoryBudget::Reservation> inflated;
    std::uint64_t wanted = 0;
    limits.reserve = [&](std::uint64_t total) {
      wanted = total;
      if (total > ctx.memory.capacity()) return false;
      std::optional<MemoryBudget::Reservation> r = ctx.memory.try_reserve(total);
      if (!r) return false;
      inflated.emplace(std::move(*r));
      return true;
    };
    std::optional<std::vector<api::ArchivePart>> parts;
    try {
      parts = job_parts(bytes, parameters.request, limits);
    } catch (const api::ArchiveError& e) {
      if (e.reason() == "memory_budget" && wanted <= ctx.memory.capacity())
        return ctx.respond(res, ctx.memory_busy_problem(wanted));
      throw;
    }
    api::RefinePlan plan =
        parts ? plan_parts_job(parameters, *parts, &result_bytes)
              : api::plan_body(std::move(parameters), bytes, api::ResultSink::JobFiles);
    const api::MemoryEstimate& predicted = plan.memory;
    if (predicted.peak_bytes > ctx.memory.capacity())
      return ctx.respond(res, api::memory_budget_problem(predicted, ctx.memory.capacity()));
    const std::size_t q = req.target.find('?');
    std::string query = q == std::string::npos ? "" : req.target.substr(q + 1);
    if (result_bytes == 0) result_bytes = predicted_result_bytes(plan.request, predicted);
    const SubmitResult submitted =
        ctx.stopping
            ? SubmitResult::refused(SubmitResult::Status::ShuttingDown)
            : ctx.jobs->submit(std::move(plan), std::move(query), body, ctx.tenant(req),
                               result_bytes, std::move(upload.name), std::move(callback_url));
    if (submitted.status == SubmitResult::Status::NoSpace)
      return ctx.respond(res, no_space_problem(submitted));
    const std::optional<JobView>& job = submitted.job;
    if (!job) {
      api::Problem p =
          submitted.status == SubmitResult::Status::ShuttingDown
              ? ctx.busy_problem(true)
              : api::service_unavailable("queue-full", "the job queue is full; retry later");
      return ctx.respond(res, p);
    }
    res.status = api::http::kAccepted;
    res.set_header("Location", "/v1/jobs/" + job->id);
    res.set_content(
        job_json(*job).dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n",
        kJsonContentType);
  } catch (const api::ArchiveError& e) {
    ctx.respond(res, archive_problem(e));
  } catch (const Error& e) {
    ctx.respond(res, api::problem_from_error(e));
  }
}

void serve_job_item(const RouteContext& ctx, const HttpRequest& req, HttpAnswer& res) {
  // /v1/jobs/{id} or /v1/jobs/{id}/{file}
  const std::string rest = req.path.substr(std::string_view("/v1/jobs/").size());
  const std::size_t slash = rest.find('/');
  const std::string id = rest.substr(0, slash);
  const std::string file = slash == std::string::npos ? "" : rest.substr(slash + 1);
  if (slash != std::string::npos && !job_file_name(file) && file != "events")
    return ctx.respond(res, api::not_found("not-found", "no route " + shortened(req.path)));
  if (!file.empty() && req.method == "DELETE") {
    api::Problem p = api::method_not_allowed(
        "method-not-allowed", "DELETE is not allowed on a job's files (allowed: GET, HEAD)");
    p.extensions["allow"] = "GET, HEAD";
    return ctx.respond(res, p);
  }
  JobView job;
  // Another tenant's job is Unknown, exactly as an id that was never issued.
  const std::string owner = ctx.tenant(req);
  const JobStore::Lookup found =
      req.method == "DELETE" ? ctx.jobs->cancel(id, owner, &job) : ctx.jobs->find(id, owner, &job);
  if (found == JobStore::Lookup::Unknown)
    return ctx.respond(res, api::not_found("unknown-job", "no job " + shortened(id)));
  if (req.method == "DELETE") {
    // A cancel either wins (the job ends cancelled, whatever the runner was doing) or says
    // it came too late: the job had finished, and DELETE removed its results.
    nlohmann::ordered_json j = job_json(job);
    if (found == JobStore::Lookup::TooLate) {
      j["cancel"] = "too_late";
      j["cancel_detail"] = "the job had already ended " + std::string(to_string(job.state)) +
                           "; its results were deleted";
    } else if (found == JobStore::Lookup::Expired) {
      j["cancel"] = "too_late";
      j["cancel_detail"] = "the job had already ended and its results were removed";
    } else {
      // A running job stops at its next cancellation check and then reads "cancelled".
      j["cancel"] = "cancelled";
    }
    res.set_content(j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n",
                    kJsonContentType);
    return;
  }
  if (found == JobStore::Lookup::Expired && (req.method != "DELETE" && !file.empty())) {
    return ctx.respond(res, api::gone("expired", "the results of job " + id +
                                                     " were removed after the retention period"));
  }
  if (file == "events") return serve_job_events(ctx, req, id, res);
  if (file.empty()) {
    if (found == JobStore::Lookup::Expired && req.method != "DELETE") res.status = api::http::kGone;
    res.set_content(
        job_json(job).dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n",
        kJsonContentType);
    return;
  }
  if (job.state != JobState::Done) {
    api::Problem p =
        api::conflict("not-done", "job " + id + " is " + to_string(job.state) + ", not done");
    p.extensions["state"] = to_string(job.state);
    return ctx.respond(res, p);
  }
  if (std::find(job.results.begin(), job.results.end(), file) == job.results.end())
    return ctx.respond(res, api::not_found("no-such-result", "job " + id + " has no " + file));
  // The front end sends the file from its descriptor: results can be large. It was written by
  // rename, so it is complete; the open descriptor keeps it readable if it expires meanwhile.
  const int fd = ::open(ctx.jobs->result_path(id, file).c_str(), O_RDONLY | O_CLOEXEC);
  struct stat st {};
  if (fd < 0 || ::fstat(fd, &st) != 0) {
    if (fd >= 0) ::close(fd);
    return ctx.respond(res, api::gone("expired", "the results of job " + id + " are gone"));
  }
  res.large.file = fd;
  res.large.file_length = static_cast<std::uint64_t>(st.st_size);
  const std::size_t dot = file.rfind('.');
  const std::string ext = file.substr(dot);
  const char* type = ext == ".stl"    ? kStlContentType
                     : ext == ".3mf"  ? k3mfContentType
                     : ext == ".zip"  ? kZipContentType
                     : ext == ".json" ? kJsonContentType
                     : ext == ".svg"  ? slicer::media_type(slicer::SliceFormat::Svg)
                                      : "application/octet-stream";
  res.set_header("Content-Type", type);
  // result.stl -> part_refined.stl, contours.cli -> part_slices.cli, report.json ->
  // part_report.json; a zip's part3.stl -> bracket_refined.stl (the part's own name).
  const bool part = part_file_name(file);
  const std::string kind =
      part ? (file.find(".contours.") != std::string::npos ? "contours" : "result")
           : file.substr(0, dot);
  const std::string suffix = kind == "result"     ? "_refined"
                             : kind == "contours" ? "_slices"
                                                  : "_" + kind;
  const std::string stem = download_stem(part ? part_of_file(job.report, file) : job.name);
  res.set_header("Content-Disposition", content_disposition(stem, suffix + ext));
}

}  // namespace stlrefine::server
