// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
// GET /v1/jobs/{id}/events: a job's progress as server-sent events. The stream is pulled by
// the front end's event loop (Answer::stream), so a client reading slowly, or waiting for
// a long job, holds a connection and no thread.
#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "server/job_routes.h"

namespace stlrefine::server {

namespace {

using Clock = std::chrono::steady_clock;

// The store is asked at most this often per stream, without waiting for its lock (a busy
// store is asked again at the next pull); a job of another replica is read from its
// job.json, on the event loop, so that only once a second.
constexpr auto kPollEvery = std::chrono::milliseconds(100);
constexpr auto kPollDiskEvery = std::chrono::seconds(1);
// A comment line this often keeps proxies and clients from timing an idle stream out.
constexpr auto kKeepAlive = std::chrono::seconds(15);
// Without a request deadline, a stream still ends after this long (the client reconnects).
constexpr auto kLongestStream = std::chrono::hours(1);

struct EventStream {
  JobStore* store;
  JobStore::StreamPlace place;  // its place among the open streams, given back with it
  std::string id, owner;
  Clock::time_point ends;
  Clock::time_point next_poll{}, last_write = Clock::now();
  std::string last;  // state, progress and stage of the last event
  bool first = true;
  bool retry_sent = false;

  static void event(std::string& out, const char* name, const nlohmann::ordered_json& job) {
    out.append("event: ").append(name).append("\ndata: ");
    // One line: compact JSON has no raw newline.
    out.append(job.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace));
    out.append("\n\n");
  }

  bool operator()(std::string& out) {
    const auto now = Clock::now();
    if (!retry_sent) out.append("retry: 2000\n\n");
    retry_sent = true;
    if (now < next_poll) {
      if (now - last_write >= kKeepAlive) {
        out.append(": keep-alive\n\n");
        last_write = now;
      }
      return true;
    }
    JobView job;
    bool on_disk = false;
    const std::optional<JobStore::Lookup> found = store->try_find(id, owner, &job, &on_disk);
    if (!found) return true;  // the store is busy: asked again at the next pull
    next_poll = now + (on_disk ? std::chrono::duration_cast<Clock::duration>(kPollDiskEvery)
                               : std::chrono::duration_cast<Clock::duration>(kPollEvery));
    if (*found == JobStore::Lookup::Unknown) return false;  // removed meanwhile
    const bool ended = job.state == JobState::Done || job.state == JobState::Failed ||
                       job.state == JobState::Cancelled;
    if (ended) {
      event(out, "end", job_json(job));
      return false;
    }
    // The JSON is made only for an event: most polls see nothing new.
    std::string key =
        std::string(to_string(job.state)) + " " + std::to_string(job.progress) + " " + job.stage;
    if (first || key != last) {
      event(out, "progress", job_json(job));
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
  // Capped in all and per tenant: each open stream is a connection and a poll on the event
  // loop. Without API keys only in all: behind a reverse proxy (the shipped nginx) every
  // client has the proxy's address, so a cap per address would let one client's streams
  // shut out everyone else's. Each stream is then its own "tenant" for the store's count.
  bool whole = false;
  const bool keyed = !ctx.config.api_keys.empty();
  static std::atomic<std::uint64_t> anonymous{0};
  std::string who = stream->owner;
  if (!keyed) who = std::string("\x01stream-").append(std::to_string(++anonymous));
  stream->place = ctx.jobs->open_stream(who, &whole);
  if (!stream->place) {
    const JobsConfig& limits = ctx.jobs->config();
    api::Problem p = api::too_many_requests(
        "too-many-streams",
        whole ? "all " + std::to_string(limits.max_event_streams) +
                    " event streams of this server are open; retry later or poll the job"
              : "this API key has " + std::to_string(limits.max_event_streams_per_tenant) +
                    " event streams open already; close one, or poll the job");
    p.extensions["reason"] = whole ? "max_event_streams" : "max_event_streams_per_tenant";
    p.extensions["limit"] = whole ? limits.max_event_streams : limits.max_event_streams_per_tenant;
    return ctx.respond(res, p);
  }
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
