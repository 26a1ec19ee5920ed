// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
// The job store's queue mode (issue 20): the routes call the same JobStore, but a job lives in
// Redis (server/queue_redis.h) and its files in the data directory every replica shares.
// Submit writes the input and queues the job; every replica's runners take jobs through one
// consumer group and compute them with the embedded store's runner (job_runner.cpp); a lease
// keeper renews the leases of this replica's running jobs, publishes their progress and
// passes cancels on; any replica answers for any job from its hash.
#include <algorithm>
#include <limits>
#include <map>
#include <optional>
#include <thread>

#include "core/error.h"
#include "server/job_record.h"

namespace stlrefine::server {

namespace fs = std::filesystem;
using namespace job_files;

namespace {

// Each Redis call's reply: a hung Redis holds an HTTP thread at most this long.
constexpr auto kCallTimeout = std::chrono::milliseconds(1000);
// A runner waits this long for a new entry, then looks at shutdown and silent entries.
constexpr auto kBlock = std::chrono::milliseconds(600);
// How often a runner looks for entries whose runner went silent (XAUTOCLAIM).
constexpr auto kReclaimEvery = std::chrono::milliseconds(1000);
// A runner records a job's end for this long while Redis is away (restarting), then leaves it
// to be taken over and run again.
constexpr auto kFinishPatience = std::chrono::seconds(30);
// A DELETE that meets a job being recorded as ended waits this long for that record.
constexpr auto kFinishingWait = std::chrono::seconds(5);
// A runner's pause after a failed call to Redis (its connection adds the back-off).
constexpr auto kRetryPause = std::chrono::milliseconds(250);
// Finished jobs one janitor pass expires at most.
constexpr std::size_t kExpireBatch = 256;
// Ids a job list reads per page (newest first), and pages it reads at most.
constexpr std::size_t kListScan = 2000;
constexpr std::size_t kListPages = 50;

std::int64_t now_ms() {
  return epoch_ms(Clock::now());
}

std::string dump(const nlohmann::ordered_json& j) {
  return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

std::string get(const JobFields& f, const char* key) {
  const auto it = f.find(key);
  return it == f.end() ? std::string() : it->second;
}

std::int64_t get_int(const JobFields& f, const char* key) {
  try {
    const std::string v = get(f, key);
    return v.empty() ? 0 : std::stoll(v);
  } catch (const std::exception&) {
    return 0;
  }
}

// A finished job keeps its hash twice the retention: its results for one, then a 410
// tombstone for another (as the embedded store keeps its job.json).
std::chrono::seconds keep(const JobsConfig& c) {
  return 2 * std::max(c.retention, std::chrono::seconds(1));
}

}  // namespace

JobFields JobStore::fields_of(const Job& job) const {
  JobFields f;
  f["id"] = job.id;
  f["tenant"] = job.tenant;
  f["state"] = to_string(job.state);
  f["expired"] = job.expired ? "1" : "0";
  f["scheme"] = job.scheme;
  f["parameters"] = job.query;
  f["name"] = job.name;
  f["callback_url"] = job.callback_url;
  f["progress"] = std::to_string(job.progress);
  f["stage"] = job.stage;
  f["created_ms"] = std::to_string(epoch_ms(job.created));
  f["started_ms"] = std::to_string(epoch_ms(job.started));
  f["finished_ms"] = std::to_string(epoch_ms(job.finished));
  f["report"] = dump(job.report);
  if (job.problem) f["problem"] = dump(*job.problem);
  f["results"] = dump(nlohmann::ordered_json(job.results));
  f["result_bytes"] = std::to_string(job.result_bytes);
  f["worker"] = job.instance;
  return f;
}

std::shared_ptr<JobStore::Job> JobStore::job_of(const JobFields& f) const {
  auto job = std::make_shared<Job>();
  job->id = get(f, "id");
  // The id names a directory whose files are read and removed: only what a store writes.
  if (!well_formed_id(job->id))
    throw std::runtime_error("a job's hash in Redis has a malformed id: " + job->id.substr(0, 64));
  job->dir = config_.data_dir / job->id;
  job->tenant = get(f, "tenant");
  job->instance = get(f, "worker");
  job->state = state_from(get(f, "state"));
  job->expired = get(f, "expired") == "1";
  job->scheme = get(f, "scheme");
  job->query = get(f, "parameters");
  job->name = get(f, "name");
  job->callback_url = get(f, "callback_url");
  try {
    job->progress = std::stod(get(f, "progress"));
  } catch (const std::exception&) {
    job->progress = 0;
  }
  job->stage = get(f, "stage");
  job->created = from_epoch_ms(get_int(f, "created_ms"));
  job->started = from_epoch_ms(get_int(f, "started_ms"));
  job->finished = from_epoch_ms(get_int(f, "finished_ms"));
  const auto json = [&](const char* key) {
    const std::string text = get(f, key);
    return text.empty() ? nlohmann::ordered_json()
                        : nlohmann::ordered_json::parse(text, nullptr, false);
  };
  if (auto r = json("report"); r.is_object()) job->report = std::move(r);
  if (auto p = json("problem"); p.is_object()) job->problem = std::move(p);
  if (auto r = json("results"); r.is_array())
    for (const auto& name : r)
      if (name.is_string()) job->results.push_back(name.get<std::string>());
  job->result_bytes =
      static_cast<std::uint64_t>(std::max<std::int64_t>(0, get_int(f, "result_bytes")));
  return job;
}

void JobStore::start_queue() {
  // A malformed address stops the daemon at its start, with what is wrong with it.
  RedisAddress address = parse_redis_address(config_.queue);
  redis_ = std::make_unique<RedisQueue>(std::move(address), config_.instance, kCallTimeout);
  figures_ = std::make_unique<QueueFigures>();
  try {
    auto c = redis_->pool().take();
    redis_->ensure_group(*c);
    figures_->reachable = true;
  } catch (const std::exception& e) {
    // Redis may come up after the daemons (compose, k8s): runners and the keeper retry.
    log_line(std::string("queue: ") + e.what() + "; retrying in the background");
  }
}

std::optional<JobStore::QueueStats> JobStore::queue_stats() const {
  if (!figures_) return std::nullopt;
  return QueueStats{figures_->reachable, figures_->depth, figures_->pending, figures_->reclaims,
                    figures_->attempts};
}

SubmitResult JobStore::submit_queued(const std::shared_ptr<Job>& job, std::string_view stl_bytes,
                                     std::uint64_t predicted_result_bytes) {
  using Status = SubmitResult::Status;
  {
    std::lock_guard lock(mutex_);
    if (stopping_) return SubmitResult::refused(Status::ShuttingDown);
  }
  auto c = redis_->pool().take();  // RedisUnavailable: the daemon answers 503
  const RedisQueue::Stats stats = redis_->stats(*c);
  if (static_cast<std::uint64_t>(stats.depth) >= config_.max_queued)
    return SubmitResult::refused(Status::QueueFull);
  // Free space of the shared directory; what other replicas accepted meanwhile is not counted.
  const std::uint64_t needed = saturating_add(
      saturating_add(stl_bytes.size(), predicted_result_bytes), config_.min_free_bytes);
  const std::uint64_t free = config_.free_bytes();
  if (free < needed) return SubmitResult::refused(Status::NoSpace, needed, free);
  try {
    fs::create_directories(job->dir);
    write_atomically(job->dir / kInputFile, stl_bytes);
    JobFields fields = fields_of(*job);
    fields["attempts"] = "0";
    fields["cancel"] = "0";
    // 3MF chosen by the request's Accept header, which the runner does not see.
    const api::RefineRequest& r = job->plan.request;
    fields["accept_3mf"] = r.mesh_format == MeshFormat::ThreeMf && !r.mesh_format_given ? "1" : "0";
    redis_->enqueue(*c, job->id, job->tenant, epoch_ms(job->created), fields);
  } catch (const RedisUnavailable&) {
    // No reply (a timeout, a connection lost): the script may have run and the job be queued.
    // Its input goes only once Redis says the job is not there (else it stays, logged).
    try {
      auto check = redis_->pool().take();
      std::error_code ignored;
      if (!redis_->load(*check, job->id)) fs::remove_all(job->dir, ignored);
    } catch (const std::exception&) {
      log_line("job " + job->id + ": unknown whether it was queued; its input stays");
    }
    throw;  // 503: the client retries (a duplicate at worst, never a queued job without input)
  } catch (const std::exception& e) {
    std::error_code ignored;
    fs::remove_all(job->dir, ignored);
    const auto* error = dynamic_cast<const std::system_error*>(&e);
    if (!error || !no_space(error->code())) throw;
    log_line("job refused: " + std::string(e.what()));
    return SubmitResult::refused(Status::NoSpace, needed, config_.free_bytes());
  }
  return {Status::Accepted, view(*job), 0, 0};
}

JobStore::Lookup JobStore::find_queued(const std::string& id, const std::string& owner,
                                       JobView* out) const {
  auto c = redis_->pool().take();
  const std::optional<JobFields> f = redis_->load(*c, id);
  if (!f || !same_tenant(get(*f, "tenant"), owner)) return Lookup::Unknown;
  const std::shared_ptr<Job> job = job_of(*f);
  if (out) *out = view(*job);
  return job->expired ? Lookup::Expired : Lookup::Found;
}

JobStore::Lookup JobStore::cancel_queued(const std::string& id, const std::string& owner,
                                         JobView* out) {
  auto c = redis_->pool().take();
  const std::string cancelled = dump(api::to_json(cancel_problem(CancelReason::Client, false)));
  RedisQueue::Cancel result = redis_->cancel(*c, id, owner, cancelled, now_ms(), keep(config_));
  if (result == RedisQueue::Cancel::Unknown) return Lookup::Unknown;
  if (result == RedisQueue::Cancel::Finishing) {
    // Its runner is recording its end (the cancel came too late for it): wait for that.
    const auto until = std::chrono::steady_clock::now() + kFinishingWait;
    while (std::chrono::steady_clock::now() < until) {
      const std::optional<JobFields> f = redis_->load(*c, id);
      if (!f) return Lookup::Unknown;
      if (finished(state_from(get(*f, "state")))) {
        redis_->mark_expired(*c, id);
        result = RedisQueue::Cancel::Finished;
        break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  }
  const std::optional<JobFields> f = redis_->load(*c, id);
  if (!f) return Lookup::Unknown;
  const std::shared_ptr<Job> job = job_of(*f);
  std::error_code ignored;
  switch (result) {
    case RedisQueue::Cancel::Expired:
      if (out) *out = view(*job);
      return Lookup::Expired;
    case RedisQueue::Cancel::Queued:
      fs::remove(job->dir / kInputFile, ignored);
      if (out) *out = view(*job);
      notify_ended(view(*job));
      return Lookup::Found;
    case RedisQueue::Cancel::Finished:
      // DELETE of a finished job frees its disk space (any replica: the directory is shared).
      for (const std::string& name : job->results) fs::remove(job->dir / name, ignored);
      if (out) *out = view(*job);
      return Lookup::TooLate;
    default:  // running (or still finishing): its runner sees the flag within a heartbeat
      if (out) {
        *out = view(*job);
        out->stage = "cancel requested";
      }
      return Lookup::Found;
  }
}

std::vector<JobView> JobStore::list_queued(const std::string& owner, std::optional<JobState> state,
                                           const std::optional<ListCursor>& after,
                                           std::size_t limit, bool* more) const {
  auto c = redis_->pool().take();
  const std::int64_t max_ms = after ? after->created_ms : std::numeric_limits<std::int64_t>::max();
  std::vector<JobView> out;
  bool over = false;
  // Page through the tenant's index (newest first) until one job more than `limit` matches:
  // a state filter may skip any number of newer jobs. New jobs sort before the offset and
  // shift it: the cursor test drops what was already seen.
  std::size_t offset = 0;
  for (std::size_t page = 0; !over; ++page) {
    if (page == kListPages) {
      over = !out.empty();  // looked far enough: the client pages on from the last one
      break;
    }
    const auto ids = redis_->tenant_jobs(*c, owner, max_ms, kListScan, offset);
    offset += ids.size();
    std::vector<std::pair<std::int64_t, std::string>> wanted;
    for (const auto& entry : ids) {
      if (after && !(entry < std::make_pair(after->created_ms, after->id))) continue;
      if (!out.empty() && !(entry < std::make_pair(epoch_ms(out.back().created), out.back().id)))
        continue;
      wanted.push_back(entry);
    }
    std::vector<std::string> keys;
    for (const auto& [created, id] : wanted) keys.push_back(id);
    const auto found = redis_->load_many(*c, keys);
    std::vector<std::string> gone;
    for (std::size_t i = 0; i < keys.size(); ++i) {
      if (!found[i]) {
        gone.push_back(keys[i]);  // its hash outlived its retention
        continue;
      }
      if (!same_tenant(get(*found[i], "tenant"), owner)) continue;
      const std::shared_ptr<Job> job = job_of(*found[i]);
      if (state && job->state != *state) continue;
      if (out.size() == limit) {
        over = true;
        break;
      }
      out.push_back(view(*job));
    }
    redis_->forget(*c, owner, gone);
    if (ids.size() < kListScan) break;
  }
  if (more) *more = over;
  return out;
}

std::optional<JobStore::Lookup> JobStore::try_find_queued(const std::string& id,
                                                          const std::string& owner, JobView* out,
                                                          bool* on_disk) const {
  // What the keeper last read (every beat); a job not watched yet is read at the next beat.
  *on_disk = true;  // polled as seldom as another replica's job
  QueueFigures& f = *figures_;
  std::unique_lock lock(f.watch_mutex, std::try_to_lock);
  if (!lock.owns_lock()) return std::nullopt;
  if (f.watched.size() >= 2 * config_.max_event_streams && !f.watched.count({id, owner}))
    return std::nullopt;
  QueueFigures::Watched& w = f.watched[{id, owner}];
  w.asked = std::chrono::steady_clock::now();
  if (!w.found) return std::nullopt;
  if (out) *out = w.view;
  return w.found;
}

void JobStore::refresh_watched() {
  // Its own connection (this thread's): the reads never delay the lease keeper's heartbeats.
  thread_local std::optional<RedisConnection> c;
  if (!c) c.emplace(redis_->pool().address(), kCallTimeout);
  QueueFigures& f = *figures_;
  std::vector<std::pair<std::string, std::string>> keys;
  {
    std::lock_guard lock(f.watch_mutex);
    const auto stale = std::chrono::steady_clock::now() - std::chrono::seconds(10);
    std::erase_if(f.watched, [&](const auto& w) { return w.second.asked < stale; });
    for (const auto& [key, w] : f.watched) keys.push_back(key);
  }
  std::vector<std::string> ids;
  for (const auto& [id, owner] : keys) ids.push_back(id);
  const auto found = redis_->load_many(*c, ids);  // one round trip
  for (std::size_t i = 0; i < keys.size(); ++i) {
    const auto& [id, owner] = keys[i];
    JobView view;
    Lookup lookup = Lookup::Unknown;
    if (found[i] && same_tenant(get(*found[i], "tenant"), owner)) {
      const std::shared_ptr<Job> job = job_of(*found[i]);
      view = this->view(*job);
      lookup = job->expired ? Lookup::Expired : Lookup::Found;
    }
    std::lock_guard lock(f.watch_mutex);
    const auto it = f.watched.find({id, owner});
    if (it == f.watched.end()) continue;
    it->second.found = lookup;
    it->second.view = std::move(view);
  }
}

void JobStore::record_queued(const Job& job) const {
  // A final state is recorded by the runner's finish_queued() (with the entry's
  // acknowledgement); what a runner records before is best effort.
  if (finished(job.state)) return;
  try {
    auto c = redis_->pool().take();
    redis_->record(*c, job.id,
                   {{"state", to_string(job.state)},
                    {"stage", job.stage},
                    {"started_ms", std::to_string(epoch_ms(job.started))}});
  } catch (const std::exception& e) {
    log_line("job " + job.id + ": cannot record its state: " + e.what());
  }
}

bool JobStore::cancel_arrived(Job& job) {
  if (!redis_) {
    std::error_code ignored;
    return fs::exists(job.dir / kCancelFile, ignored);
  }
  try {
    auto c = redis_->pool().take();
    return redis_->seal(*c, job.id);
  } catch (const std::exception& e) {
    log_line("job " + job.id + ": cannot look for a cancel: " + e.what());
    return false;
  }
}

bool JobStore::hand_back(Job& job) {
  {
    // Only what a shutdown stopped (not a client's cancel, nor a run another replica took
    // over): the job is not the client's to submit again.
    std::lock_guard lock(mutex_);
    if (!stopping_ || job.superseded || job.cancel_reason == CancelReason::Client) return false;
    job.handed_back = true;
  }
  try {
    auto c = redis_->pool().take();
    if (redis_->hand_back(*c, job.id, job.entry))
      log_line("job " + job.id + " handed back to the queue at shutdown");
    else
      log_line("job " + job.id + ": its entry was taken over by another replica; not handed back");
  } catch (const std::exception& e) {
    // Its entry stays pending: another replica takes it over after the lease.
    log_line("job " + job.id + ": cannot hand it back (" + e.what() + "); left to the lease");
  }
  return true;
}

bool JobStore::finish_queued(RedisConnection& c, Job& job) {
  const auto until = std::chrono::steady_clock::now() + kFinishPatience;
  for (;;) {
    try {
      JobFields f = fields_of(job);
      f["sealed"] = "0";
      if (!redis_->finish(c, job.id, job.entry, f, keep(config_), epoch_ms(job.finished))) {
        log_line("job " + job.id + ": its entry was taken over by another replica; not recorded");
        return false;
      }
      return true;
    } catch (const std::exception& e) {
      if (std::chrono::steady_clock::now() > until) {
        log_line("job " + job.id + ": cannot record its end (" + e.what() +
                 "); it runs again once its lease lapses");
        return false;
      }
    }
    std::this_thread::sleep_for(kRetryPause);
  }
}

void JobStore::run_entry(RedisConnection& c, const QueueEntry& entry) {
  const std::string exhausted = dump(api::to_json(api::server_error(
      "interrupted", "the job was started " + std::to_string(config_.max_attempts) +
                         " times and each time its runner stopped before it finished (killed, "
                         "or silent for longer than the lease of " +
                         std::to_string(config_.lease.count()) + " s); it is not run again")));
  const RedisQueue::Start start =
      redis_->start(c, entry.job, config_.max_attempts, exhausted, now_ms());
  if (start.kind == RedisQueue::Start::Kind::Skip) {
    redis_->drop(c, entry.entry);  // cancelled while queued, or gone
    return;
  }
  const std::shared_ptr<Job> job = job_of(start.fields);
  job->entry = entry.entry;
  std::error_code ignored;
  if (start.kind == RedisQueue::Start::Kind::Exhausted) {
    log_line("job " + job->id + " failed: too many attempts");
    job->state = JobState::Failed;
    job->stage = to_string(JobState::Failed);
    job->finished = Clock::now();
    job->problem = nlohmann::ordered_json::parse(exhausted);
    if (!finish_queued(c, *job)) return;  // told by whoever records it
    fs::remove(job->dir / kInputFile, ignored);
    notify_ended(view(*job));
    return;
  }
  ++figures_->attempts;
  job->instance = redis_->consumer();
  try {
    const std::string input = read_file(job->dir / kInputFile);
    std::string query = job->query;
    if (get(start.fields, "accept_3mf") == "1")
      query.append(query.empty() ? "" : "&").append("mesh_format=3mf");
    job->plan = config_.plan_job(query, job->name, input);
  } catch (const std::exception& e) {
    // Validated when it was submitted: only a lost input or another replica's other limits.
    const auto* error = dynamic_cast<const Error*>(&e);
    log_line("job " + job->id + " failed before it ran: " + e.what());
    job->state = JobState::Failed;
    job->stage = to_string(JobState::Failed);
    job->finished = Clock::now();
    job->problem = api::to_json(error ? api::problem_from_error(*error) : api::internal_error());
    if (!finish_queued(c, *job)) return;  // told by whoever records it
    fs::remove(job->dir / kInputFile, ignored);
    notify_ended(view(*job));
    return;
  }
  bool admitted = false;
  {
    std::lock_guard lock(mutex_);
    if (!stopping_) {
      jobs_.emplace(job->id, job);
      ++running_;
      admitted = true;
    }
  }
  if (!admitted) {
    hand_back(*job);
    return;
  }
  run_one(job);  // records its end (finish_queued) before it tells anyone
  std::lock_guard lock(mutex_);
  jobs_.erase(job->id);
  --running_;
  work_.notify_all();  // shutdown() waits for running_ == 0
}

void JobStore::run_queue_jobs() {
  // One connection per runner: XREADGROUP blocks it.
  RedisConnection c(redis_->pool().address(), kCallTimeout);
  auto last_reclaim = std::chrono::steady_clock::time_point{};
  bool away = false;  // logged once per outage
  for (;;) {
    {
      std::lock_guard lock(mutex_);
      if (stopping_) return;
    }
    // Work is taken only with a compute slot free: a job waits in the queue, where an idle
    // replica can take it, rather than in a busy runner.
    if (slots_.available() == 0) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      continue;
    }
    std::optional<QueueEntry> entry;
    try {
      const auto now = std::chrono::steady_clock::now();
      if (now - last_reclaim >= kReclaimEvery) {
        last_reclaim = now;
        entry = redis_->reclaim(c, config_.lease);
        if (entry) {
          ++figures_->reclaims;
          log_line("job " + entry->job + " taken over from a silent runner");
        }
      }
      if (!entry) entry = redis_->next(c, kBlock);
      if (away) log_line("queue: Redis is back");
      away = false;
      if (!entry) continue;
      if (!well_formed_id(entry->job)) {
        redis_->drop(c, entry->entry);  // not written by a store
        continue;
      }
      run_entry(c, *entry);
    } catch (const std::exception& e) {
      if (!away) log_line(std::string("queue: ") + e.what());
      away = true;
      try {
        redis_->ensure_group(c);  // NOGROUP: a Redis restarted without its data
      } catch (const std::exception&) {
      }
      std::this_thread::sleep_for(kRetryPause);
    }
  }
}

void JobStore::keep_leases() {
  RedisConnection c(redis_->pool().address(), kCallTimeout);
  // A cancel is seen within a beat; a lease is renewed many times before it lapses.
  const auto beat = std::clamp<std::chrono::milliseconds>(
      std::chrono::duration_cast<std::chrono::milliseconds>(config_.lease) / 4,
      std::chrono::milliseconds(50), std::chrono::milliseconds(250));
  // A run stops itself once its lease may have lapsed (no heartbeat renewed it for 0.8 of
  // it: a stall, Redis away): another replica may have taken its entry over meanwhile, and
  // this replica may not be able to ask Redis whether it did.
  const auto stale_after =
      std::chrono::duration_cast<std::chrono::milliseconds>(config_.lease) * 4 / 5;
  std::map<std::string, std::chrono::steady_clock::time_point> renewed;  // by entry
  const auto stop_stale = [&](const std::shared_ptr<Job>& job, const std::string& entry) {
    const auto it = renewed.find(entry);
    if (it == renewed.end() || std::chrono::steady_clock::now() - it->second < stale_after) return;
    std::lock_guard lock(mutex_);
    if (finished(job->state) || job->superseded) return;
    log_line("job " + job->id + ": lease not renewed for " + std::to_string(stale_after.count()) +
             " ms; stopping this run");
    job->superseded = true;
    request_cancel(*job, CancelReason::ShutdownNow);
  };
  // Jobs followed by event streams here are read on a thread of their own.
  std::thread watcher([this, beat] {
    for (;;) {
      {
        std::lock_guard lock(mutex_);
        if (stopping_) return;
      }
      try {
        refresh_watched();
      } catch (const std::exception&) {
        // Redis away: the keeper tells (queue_up); streams keep their last view.
      }
      std::this_thread::sleep_for(beat);
    }
  });
  for (;;) {
    struct Running {
      std::shared_ptr<Job> job;
      std::string entry, stage;
      double progress;
    };
    std::vector<Running> running;
    {
      std::lock_guard lock(mutex_);
      if (stopping_ && running_ == 0) break;
      for (const auto& [id, job] : jobs_)
        if (!finished(job->state)) running.push_back({job, job->entry, job->stage, job->progress});
    }
    {
      std::map<std::string, std::chrono::steady_clock::time_point> kept;
      for (const Running& r : running) {
        const auto it = renewed.find(r.entry);
        kept[r.entry] = it == renewed.end() ? std::chrono::steady_clock::now() : it->second;
        stop_stale(r.job, r.entry);
      }
      renewed = std::move(kept);
    }
    try {
      for (const Running& r : running) {
        const auto asked = std::chrono::steady_clock::now();
        const RedisQueue::Beat b =
            redis_->heartbeat(c, r.job->id, r.entry, r.progress, r.stage, now_ms());
        if (b.owned) renewed[r.entry] = asked;
        std::lock_guard lock(mutex_);
        if (finished(r.job->state)) continue;
        if (!b.owned && !r.job->superseded) {
          // Silent too long (a stall, a Redis outage): another runner has it now.
          log_line("job " + r.job->id + ": lease lost to another replica; stopping this run");
          r.job->superseded = true;
          request_cancel(*r.job, CancelReason::ShutdownNow);
        } else if (b.cancel && r.job->cancel_reason != CancelReason::Client) {
          request_cancel(*r.job, CancelReason::Client);
        }
      }
      const RedisQueue::Stats s = redis_->stats(c);
      figures_->depth = static_cast<std::uint64_t>(s.depth);
      figures_->pending = static_cast<std::uint64_t>(s.pending);
      figures_->reachable = true;
    } catch (const RedisError& e) {
      figures_->reachable = true;
      try {
        redis_->ensure_group(c);
      } catch (const std::exception&) {
      }
    } catch (const std::exception&) {
      figures_->reachable = false;  // the runners log the outage
    }
    std::this_thread::sleep_for(beat);
  }
  watcher.join();
}

void JobStore::expire_queued() {
  // Any replica's janitor may do this; removing files twice is harmless.
  auto c = redis_->pool().take();
  const auto before =
      now_ms() - std::chrono::duration_cast<std::chrono::milliseconds>(config_.retention).count();
  for (const std::string& id : redis_->due(*c, before, kExpireBatch)) {
    if (!well_formed_id(id)) {
      redis_->expired(*c, id);
      continue;
    }
    std::error_code ignored;
    fs::remove_all(config_.data_dir / id, ignored);  // the hash is its tombstone (410)
    redis_->mark_expired(*c, id);
    redis_->expired(*c, id);
  }
  // Every replica that ever ran leaves a consumer in the group (its name is unique per
  // start). A live one reads every kBlock and any with a running job has it pending, so
  // one idle for ten leases with nothing pending has stopped.
  redis_->prune_consumers(*c, 10 * config_.lease);
}

}  // namespace stlrefine::server
