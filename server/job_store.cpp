// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include <fcntl.h>
#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/hmac.h>
#include <unistd.h>

#include <algorithm>
#include <span>
#include <stdexcept>

#include "server/job_record.h"

namespace stlrefine::server {

namespace fs = std::filesystem;
using namespace job_files;

JobStore::JobStore(JobsConfig config, ComputeSlots& slots, FinishedFn on_finished)
    : config_(std::move(config)), slots_(slots), on_finished_(std::move(on_finished)) {
  if (config_.runners == 0) config_.runners = 1;
  if (config_.instance.empty()) {
    char host[256] = {};
    ::gethostname(host, sizeof host - 1);
    config_.instance = host;
    // Queue mode: the replica's consumer name, unique even for daemons on one host.
    if (!config_.queue.empty()) config_.instance.append(":").append(std::to_string(::getpid()));
  }
  if (!config_.free_bytes)
    config_.free_bytes = [dir = config_.data_dir] { return statvfs_free(dir); };
  fs::create_directories(config_.data_dir);
  tenant_key_ = load_tenant_key(config_.data_dir);
  if (config_.queue.empty())
    load_existing();
  else
    start_queue();  // the jobs are in Redis: nothing of this replica's to recover
  if (!config_.callbacks.secret.empty() && !config_.callbacks.allow.empty())
    callbacks_ = std::make_unique<CallbackSender>(config_.callbacks);
  if (config_.run_jobs)
    for (std::size_t i = 0; i < config_.runners; ++i) runners_.emplace_back([this] { run_jobs(); });
  janitor_ = std::thread([this] { janitor(); });
  if (redis_) keeper_ = std::thread([this] { keep_leases(); });
}

JobStore::~JobStore() {
  shutdown(std::chrono::milliseconds(0));
  OPENSSL_cleanse(tenant_key_.data(), tenant_key_.size());
}

std::string JobStore::tenant_of(std::string_view api_key) const {
  return tenant_id(tenant_key_, api_key);
}

JobView JobStore::view(const Job& job) const {
  JobView v;
  v.id = job.id;
  v.state = job.state;
  v.expired = job.expired;
  v.progress = job.progress;
  v.stage = job.stage;
  v.tenant = job.tenant;
  v.scheme = job.scheme;
  v.query = job.query;
  v.name = job.name;
  v.callback_url = job.callback_url;
  v.created = job.created;
  v.started = job.started;
  v.finished = job.finished;
  v.report = job.report;
  v.problem = job.problem;
  if (!job.expired) v.results = job.results;
  if (redis_) v.worker = job.instance;
  return v;
}

std::vector<JobView> JobStore::list(const std::string& owner, std::optional<JobState> state,
                                    const std::optional<ListCursor>& after, std::size_t limit,
                                    bool* more) const {
  if (redis_) return list_queued(owner, state, after, limit, more);
  // Newest first: (created, id) descending, so a cursor is a position that stays valid as
  // jobs come and go.
  using Key = std::pair<std::int64_t, std::string>;
  std::vector<std::pair<Key, const Job*>> mine;
  std::vector<JobView> out;
  std::lock_guard lock(mutex_);
  for (const auto& [id, job] : jobs_) {
    if (!same_tenant(job->tenant, owner)) continue;
    if (state && job->state != *state) continue;
    Key key{epoch_ms(job->created), id};
    if (after && key >= Key{after->created_ms, after->id}) continue;
    mine.emplace_back(std::move(key), job.get());
  }
  std::sort(mine.begin(), mine.end(),
            [](const auto& a, const auto& b) { return a.first > b.first; });
  if (more) *more = mine.size() > limit;
  for (std::size_t i = 0; i < mine.size() && i < limit; ++i) out.push_back(view(*mine[i].second));
  return out;
}

void JobStore::notify_ended(const JobView& job) {
  if (callbacks_ && !job.callback_url.empty())
    callbacks_->send(job.callback_url,
                     job_json(job).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace),
                     job.tenant);
}

void JobStore::release_disk(Job& job) {
  committed_disk_ -= std::min(committed_disk_, job.reserved_disk);
  job.reserved_disk = 0;
}

SubmitResult JobStore::submit(api::RefineRequest request, std::string query,
                              std::string_view stl_bytes, std::string owner,
                              std::uint64_t predicted_result_bytes) {
  const auto bytes =
      std::span(reinterpret_cast<const std::uint8_t*>(stl_bytes.data()), stl_bytes.size());
  return submit(api::plan_refine(std::move(request), bytes, api::ResultSink::JobFiles),
                std::move(query), stl_bytes, std::move(owner), predicted_result_bytes);
}

SubmitResult JobStore::submit(api::RefinePlan plan, std::string query, std::string_view stl_bytes,
                              std::string owner, std::uint64_t predicted_result_bytes,
                              std::string name, std::string callback_url) {
  using Status = SubmitResult::Status;
  std::uint64_t needed = 0;
  auto job = std::make_shared<Job>();
  job->id = new_job_id();
  job->instance = config_.instance;
  job->tenant = std::move(owner);
  job->dir = config_.data_dir / job->id;
  job->scheme = plan.request.refine.scheme;
  job->query = std::move(query);
  job->name = std::move(name);
  job->callback_url = std::move(callback_url);
  job->plan = std::move(plan);
  job->created = Clock::now();
  if (redis_) return submit_queued(job, stl_bytes, predicted_result_bytes);
  const std::uint64_t input = stl_bytes.size();
  const std::uint64_t reserve = saturating_add(input, predicted_result_bytes);
  {
    // Checked and reserved under the lock: jobs accepted together cannot all count on the
    // same free space. (statvfs is one quick system call.)
    std::lock_guard lock(mutex_);
    if (stopping_) return SubmitResult::refused(Status::ShuttingDown);
    if (queue_.size() >= config_.max_queued) return SubmitResult::refused(Status::QueueFull);
    const std::uint64_t free = config_.free_bytes();
    needed = saturating_add(saturating_add(reserve, committed_disk_), config_.min_free_bytes);
    if (free < needed) return SubmitResult::refused(Status::NoSpace, needed, free);
    committed_disk_ = saturating_add(committed_disk_, reserve);
  }
  // The input goes to disk before the job is visible, so a queued job holds no memory. A
  // failed write leaves no directory behind (and no job.json-less directory ever).
  try {
    fs::create_directories(job->dir);
    write_atomically(job->dir / kInputFile, stl_bytes);
    persist(*job);
  } catch (const std::exception& e) {
    std::error_code ignored;
    fs::remove_all(job->dir, ignored);
    {
      std::lock_guard lock(mutex_);
      committed_disk_ -= std::min(committed_disk_, reserve);
    }
    const auto* error = dynamic_cast<const std::system_error*>(&e);
    if (!error || !no_space(error->code())) throw;
    log_line("job refused: " + std::string(e.what()));
    return SubmitResult::refused(Status::NoSpace, needed, config_.free_bytes());
  }
  std::lock_guard lock(mutex_);
  committed_disk_ -= std::min(committed_disk_, input);  // on disk now: statvfs sees it
  job->reserved_disk = predicted_result_bytes;
  if (stopping_ || queue_.size() >= config_.max_queued) {
    release_disk(*job);
    std::error_code ignored;
    fs::remove_all(job->dir, ignored);
    return SubmitResult::refused(stopping_ ? Status::ShuttingDown : Status::QueueFull);
  }
  jobs_.emplace(job->id, job);
  queue_.push_back(job);
  work_.notify_one();
  return {Status::Accepted, view(*job), 0, 0};
}

JobStore::Lookup JobStore::find_on_disk(const std::string& id, const std::string& owner,
                                        JobView* out) const {
  if (!well_formed_id(id)) return Lookup::Unknown;
  std::error_code ec;
  if (!fs::exists(config_.data_dir / id / kJobFile, ec)) return Lookup::Unknown;
  try {
    const std::shared_ptr<Job> job = read_job(config_.data_dir / id);
    if (!same_tenant(job->tenant, owner)) return Lookup::Unknown;
    if (out) *out = view(*job);
    return job->expired ? Lookup::Expired : Lookup::Found;
  } catch (const std::exception&) {
    return Lookup::Unknown;  // being written by its owner for the first time
  }
}

JobStore::Lookup JobStore::find(const std::string& id, const std::string& owner,
                                JobView* out) const {
  if (!well_formed_id(id)) return Lookup::Unknown;
  if (redis_) return find_queued(id, owner, out);
  {
    std::lock_guard lock(mutex_);
    const auto it = jobs_.find(id);
    if (it != jobs_.end()) {
      const Job& job = *it->second;
      if (!same_tenant(job.tenant, owner)) return Lookup::Unknown;
      if (out) *out = view(job);
      return job.expired ? Lookup::Expired : Lookup::Found;
    }
  }
  return find_on_disk(id, owner, out);
}

void JobStore::request_cancel(Job& job, CancelReason why) {
  // A shutdown's reason stays the first; the client's replaces it: a cancel answered Found
  // must end the job cancelled, which a shutdown cancel of a job just done does not.
  if (job.cancel_reason == CancelReason::None || why == CancelReason::Client)
    job.cancel_reason = why;
  job.cancel = true;
  if (job.ticket)
    job.ticket->raise(why == CancelReason::Client ? RequestWatch::Reason::Cancelled
                                                  : RequestWatch::Reason::Shutdown);
}

bool JobStore::cancel_noted(Job& job) {
  if (redis_) return false;  // the lease keeper raises job.cancel (queue_store.cpp)
  std::error_code ec;
  if (!fs::exists(job.dir / kCancelFile, ec)) return false;
  std::lock_guard lock(mutex_);
  request_cancel(job, CancelReason::Client);
  return true;
}

api::Problem JobStore::cancel_problem(CancelReason why, bool discarded) const {
  if (why == CancelReason::ShutdownGrace || why == CancelReason::ShutdownNow) {
    char grace[32];
    std::snprintf(grace, sizeof grace, "%g", std::chrono::duration<double>(grace_).count());
    api::Problem p = api::service_unavailable(
        "shutting-down",
        why == CancelReason::ShutdownGrace
            ? std::string("cancelled at shutdown: the server stopped and this job did not finish "
                          "within the shutdown grace period of ") +
                  grace + " s; submit it again"
            : std::string("cancelled at shutdown: the server was told to stop at once (a "
                          "second termination signal) before this job finished; submit it "
                          "again"));
    p.extensions["reason"] = "shutdown";
    return p;
  }
  if (why == CancelReason::None) return api::conflict("cancelled", "cancelled");
  return api::conflict("cancelled", discarded
                                        ? "cancelled by the client (its results, ready an instant "
                                          "later, were discarded)"
                                        : "cancelled by the client");
}

void JobStore::end_unrun(Job& job, const char* stage, const api::Problem& failure) const {
  std::error_code ignored;
  job.finished = Clock::now();
  if (fs::exists(job.dir / kCancelFile, ignored)) {  // accepted by another replica
    job.state = JobState::Cancelled;
    job.stage = "cancelled";
    job.problem = api::to_json(cancel_problem(CancelReason::Client, false));
  } else {
    job.state = JobState::Failed;
    job.stage = stage;
    job.problem = api::to_json(failure);
  }
}

JobStore::Lookup JobStore::cancel(const std::string& id, const std::string& owner, JobView* out) {
  if (!well_formed_id(id)) return Lookup::Unknown;
  if (redis_) return cancel_queued(id, owner, out);
  {
    std::lock_guard lock(mutex_);
    const auto it = jobs_.find(id);
    if (it != jobs_.end()) {
      Job& job = *it->second;
      if (!same_tenant(job.tenant, owner)) return Lookup::Unknown;
      if (job.expired) {
        if (out) *out = view(job);
        return Lookup::Expired;
      }
      if (finished(job.state)) {
        expire(job);  // DELETE of a finished job frees its disk space
        if (out) *out = view(job);
        return Lookup::TooLate;
      }
      // From here the job ends cancelled: the runner checks cancel_reason under this lock
      // before it marks the job done.
      request_cancel(job, CancelReason::Client);
      if (job.state == JobState::Queued) {
        queue_.erase(std::remove(queue_.begin(), queue_.end(), it->second), queue_.end());
        job.state = JobState::Cancelled;
        job.stage = "cancelled";
        job.finished = Clock::now();
        job.problem = api::to_json(cancel_problem(CancelReason::Client, false));
        release_disk(job);
        std::error_code ignored;
        fs::remove(job.dir / kInputFile, ignored);
        persist_or_log(job);
        notify_ended(view(job));
      }
      if (out) {
        *out = view(job);
        if (job.state == JobState::Running) out->stage = "cancel requested";
      }
      return Lookup::Found;
    }
  }
  return cancel_on_disk(id, owner, out);
}

JobStore::Lookup JobStore::cancel_on_disk(const std::string& id, const std::string& owner,
                                          JobView* out) {
  // Another replica's job: leave a note its runner (running) or janitor (finished) picks
  // up. Under the directory's lock, so the owner cannot finish it between our look and our
  // note unnoticed.
  const fs::path dir = config_.data_dir / id;
  std::error_code ec;
  if (!fs::exists(dir / kJobFile, ec)) return Lookup::Unknown;
  DirLock lock(dir);
  JobView job;
  const Lookup found = find_on_disk(id, owner, &job);
  if (found != Lookup::Found) {
    if (found == Lookup::Expired && out) *out = job;
    return found;
  }
  const bool done = finished(job.state);
  const fs::path note = dir / (done ? kDeleteFile : kCancelFile);
  const int fd = ::open(note.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) throw_errno(errno, "cannot write " + note.string());
  ::close(fd);
  if (out) {
    *out = job;
    if (!done) out->stage = "cancel requested";
  }
  return done ? Lookup::TooLate : Lookup::Found;
}

fs::path JobStore::result_path(const std::string& id, const std::string& name) const {
  return config_.data_dir / id / name;
}

std::size_t JobStore::queued() const {
  if (figures_) return figures_->depth;  // every replica's queue, as last seen
  std::lock_guard lock(mutex_);
  return queue_.size();
}

std::size_t JobStore::running() const {
  std::lock_guard lock(mutex_);
  return running_;
}

void JobStore::cancel_running() {
  cancel_running(CancelReason::ShutdownNow);
}

void JobStore::cancel_running(CancelReason why) {
  std::lock_guard lock(mutex_);
  if (shutdown_reason_ == CancelReason::None) shutdown_reason_ = why;
  cancel_all_ = true;
  for (auto& [id, job] : jobs_)
    if (job->state == JobState::Running) request_cancel(*job, why);
}

void JobStore::shutdown(std::chrono::milliseconds grace) {
  {
    std::unique_lock lock(mutex_);
    if (!stopping_) {
      stopping_ = true;
      grace_ = grace;
      for (const auto& job : queue_) {
        std::error_code ignored;
        end_unrun(
            *job, "shutting down",
            api::service_unavailable(
                "shutting-down", "the server shut down before this job started; submit it again"));
        release_disk(*job);
        fs::remove(job->dir / kInputFile, ignored);
        persist_or_log(*job);
      }
      queue_.clear();
    }
    work_.notify_all();
    janitor_wake_.notify_all();
    // Running jobs may finish within the grace period; then they are cancelled.
    if (!work_.wait_for(lock, grace, [&] { return running_ == 0; })) {
      lock.unlock();
      cancel_running(CancelReason::ShutdownGrace);
    }
  }
  for (std::thread& t : runners_)
    if (t.joinable()) t.join();
  if (janitor_.joinable()) janitor_.join();
  if (keeper_.joinable()) keeper_.join();
}

}  // namespace stlrefine::server
