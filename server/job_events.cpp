// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
// GET /v1/jobs/{id}/events: a job's progress as server-sent events. The stream is pulled by
// the front end's event loop (Answer::stream), so a client reading slowly, or waiting for
// a long job, holds a connection and no thread.
#include <chrono>
#include <memory>

#include "server/job_routes.h"

namespace stlrefine::server {

namespace {

using Clock = std::chrono::steady_clock;

// The store is asked at most this often per stream (a job of another replica is read from
// disk).
constexpr auto kPollEvery = std::chrono::milliseconds(100);
// A comment line this often keeps proxies and clients from timing an idle stream out.
constexpr auto kKeepAlive = std::chrono::seconds(15);
// Without a request deadline, a stream still ends after this long (the client reconnects).
constexpr auto kLongestStream = std::chrono::hours(1);

struct EventStream {
  JobStore* store;
  std::string id, owner;
  Clock::time_point ends;
  Clock::time_point next_poll{}, last_write = Clock::now();
  std::string last;  // state, progress and stage of the last event
  bool first = true;

  static void event(std::string& out, const char* name, const nlohmann::ordered_json& job) {
    out.append("event: ").append(name).append("\ndata: ");
    // One line: compact JSON has no raw newline.
    out.append(job.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace));
    out.append("\n\n");
  }

  bool operator()(std::string& out) {
    const auto now = Clock::now();
    if (first) out.append("retry: 2000\n\n");
    if (now < next_poll) {
      if (now - last_write >= kKeepAlive) {
        out.append(": keep-alive\n\n");
        last_write = now;
      }
      return true;
    }
    next_poll = now + kPollEvery;
    JobView job;
    const JobStore::Lookup found = store->find(id, owner, &job);
    if (found == JobStore::Lookup::Unknown) return false;  // removed meanwhile
    const nlohmann::ordered_json j = job_json(job);
    const bool ended = job.state == JobState::Done || job.state == JobState::Failed ||
                       job.state == JobState::Cancelled;
    if (ended) {
      event(out, "end", j);
      return false;
    }
    std::string key = j["state"].dump() + j["progress"].dump() + j["stage"].dump();
    if (first || key != last) {
      event(out, "progress", j);
      last = std::move(key);
      last_write = now;
    } else if (now - last_write >= kKeepAlive) {
      out.append(": keep-alive\n\n");
      last_write = now;
    }
    first = false;
    if (now >= ends) {
      out.append(
          "event: timeout\ndata: {\"detail\":\"the stream reached the server's deadline; "
          "reconnect to follow the job further\"}\n\n");
      return false;
    }
    return true;
  }
};

}  // namespace

void serve_job_events(const RouteContext& ctx, const HttpRequest& req, const std::string& id,
                      HttpAnswer& res) {
  auto stream = std::make_shared<EventStream>();
  stream->store = ctx.jobs;
  stream->id = id;
  stream->owner = ctx.tenant(req);
  stream->ends =
      Clock::now() + (ctx.config.request_deadline.count() > 0
                          ? std::chrono::duration_cast<Clock::duration>(ctx.config.request_deadline)
                          : std::chrono::duration_cast<Clock::duration>(kLongestStream));
  res.set_header("Content-Type", "text/event-stream; charset=utf-8");
  res.set_header("Cache-Control", "no-cache");
  res.set_header("X-Accel-Buffering", "no");  // nginx: pass events on as they come
  res.large.stream = [stream](std::string& out) { return (*stream)(out); };
}

}  // namespace stlrefine::server
