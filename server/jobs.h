// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "api/memory_model.h"
#include "api/params.h"
#include "api/plan.h"
#include "api/problem.h"
#include "server/compute_slots.h"
#include "server/job_callbacks.h"
#include "server/memory_budget.h"
#include "server/request_watch.h"

namespace stlrefine::server {

class RedisConnection;
class RedisQueue;
struct QueueEntry;

enum class JobState { Queued, Running, Done, Failed, Cancelled };
const char* to_string(JobState state);

//! The problem of a computation cancelled at its deadline: 504 deadline-exceeded, reason
//! "deadline_exceeded", `deadline_seconds`.
api::Problem deadline_problem(std::chrono::milliseconds deadline);

struct JobsConfig {
  //! Where inputs, results and each job's job.json live (created if missing). Empty means
  //! no jobs (the daemon's default; stlrefined defaults to ./stlrefine-data).
  std::filesystem::path data_dir;
  //! Jobs waiting for a compute slot; one more is refused (503 + Retry-After).
  std::size_t max_queued = 16;
  //! Finished jobs keep their results this long, then answer 410 Gone.
  std::chrono::seconds retention{std::chrono::hours(24)};
  //! Result bytes kept on disk at most; the oldest finished jobs expire first.
  std::uint64_t disk_budget_bytes = std::uint64_t{10} << 30;
  //! Job runners (each takes a compute slot shared with the synchronous routes).
  std::size_t runners = 1;
  //! This daemon's name among replicas sharing data_dir (default: the host name). A job is
  //! run, recovered and expired by its owner; any replica answers for it from disk.
  std::string instance;
  //! When set, a job reserves its predicted peak (api/memory_model.h) here before it runs,
  //! waiting for it like for a compute slot; a job that could never fit fails (422).
  MemoryBudget* memory = nullptr;
  //! A job computing longer is cancelled and fails with "deadline exceeded"; 0 = never.
  std::chrono::milliseconds deadline{0};
  //! Runners compute at this much lower priority (nice increment), as the HTTP workers do.
  int runner_nice = 0;
  //! Kept free on the data directory's file system beyond each job's input, its predicted
  //! results and those of the jobs accepted before it: a job that would eat into it is
  //! refused (SubmitResult::Status::NoSpace, 507).
  std::uint64_t min_free_bytes = std::uint64_t{64} << 20;
  //! Free bytes of the data directory's file system (empty: statvfs's f_bavail * f_frsize;
  //! a file system it cannot measure counts as unlimited). Tests inject their own.
  std::function<std::uint64_t()> free_bytes;
  //! Where and how `callback_url`s are called (job_callbacks.h); without a secret and an
  //! allow-list, a job with one is refused.
  CallbackPolicy callbacks;

  // Queue mode (issue 20, server/queue_store.cpp): the jobs of every replica in one Redis.
  //! "redis://HOST:PORT[/DB]" or "unix:///PATH[?db=N]"; empty: the embedded store above.
  std::string queue;
  //! Whether this replica runs jobs (--role worker|all); an api replica only queues them.
  bool run_jobs = true;
  //! A running job's entry silent this long is taken over by another replica's runner.
  std::chrono::seconds lease{30};
  //! Runs of a job whose runner stopped before it finished; one more fails it.
  int max_attempts = 3;
  //! Queue mode: a runner plans a job taken from the queue again from what was submitted
  //! (its parameters, its file's name, its input). Set by the daemon (it has the limits).
  std::function<api::RefinePlan(const std::string& query, const std::string& name,
                                std::string_view input)>
      plan_job;
  //! Event streams (GET /v1/jobs/{id}/events) open at once, in all and per tenant (per
  //! client address without API keys): one more is refused (429 + Retry-After).
  std::size_t max_event_streams = 256;
  std::size_t max_event_streams_per_tenant = 32;
};

//! What a client sees of a job (a copy, taken under the store's lock).
struct JobView {
  std::string id;
  JobState state = JobState::Queued;
  bool expired = false;  //!< results removed after retention (410)
  double progress = 0;   //!< [0, 1]
  std::string stage;     //!< "queued", "level 2/3", "slicing", "done", ...
  std::string scheme;
  std::string query;         //!< the parameters as submitted
  std::string name;          //!< the uploaded file's name (http_upload.h's upload_name), or empty
  std::string callback_url;  //!< POSTed the job's JSON when it ends; empty: none
  std::string tenant;        //!< its owner (never shown: it signs the callback)
  std::chrono::system_clock::time_point created, started, finished;
  nlohmann::ordered_json report;                  //!< the refine report once done
  std::optional<nlohmann::ordered_json> problem;  //!< RFC 9457 body once failed/cancelled
  std::vector<std::string> results;               //!< file names ready for download
  std::string worker;  //!< queue mode: the replica that runs or ran it; empty otherwise
};

//! Seconds a running job still needs, from its progress and its run time so far; 0 when
//! done; null (JSON) until that is meaningful and for a job not running.
nlohmann::ordered_json eta_seconds(const JobView& job);

//! The job's JSON answer: id, state, progress, stage, eta_seconds, timings, report,
//! problem, links.
nlohmann::ordered_json job_json(const JobView& job);

//! What JobStore::submit did with a job.
struct SubmitResult {
  enum class Status {
    Accepted,      //!< queued: `job` is set (202)
    QueueFull,     //!< max_queued jobs wait already (503 + Retry-After)
    ShuttingDown,  //!< the store takes no more jobs (503)
    NoSpace,       //!< the data directory's file system is too full (507)
  };
  Status status = Status::Accepted;
  std::optional<JobView> job;
  //! NoSpace: what the job needed free (input + predicted results + the predicted results
  //! of the jobs accepted and not finished + min_free_bytes) and what was free. After a
  //! write that failed for want of space (ENOSPC, EDQUOT, EFBIG), free_bytes is what the
  //! file system said afterwards.
  std::uint64_t needed_bytes = 0;
  std::uint64_t free_bytes = 0;

  //! A job not accepted, for `status`.
  static SubmitResult refused(Status status, std::uint64_t needed_bytes = 0,
                              std::uint64_t free_bytes = 0) {
    return {status, std::nullopt, needed_bytes, free_bytes};
  }
};

//! The 507 answer to SubmitResult::Status::NoSpace: insufficient-storage, reason
//! "no_space", `needed_bytes`, `free_bytes`.
api::Problem no_space_problem(const SubmitResult& refused);

//! Bytes a job's files take at most on disk (the figure submit() checks free space for):
//! the STL of `predicted.output_faces` facets in the request's output format, the contours
//! of `predicted.contour_points` points at the widest format's size, and the report.
//! (api::MemoryEstimate::answer_bytes is 0 for ResultSink::JobFiles.)
std::uint64_t predicted_result_bytes(const api::RefineRequest& request,
                                     const api::MemoryEstimate& predicted);

//! Asynchronous refinement jobs (refine, optionally slice) with a bounded queue, results in
//! a data directory written by atomic rename, retention by age and disk budget, and
//! recovery after a restart: finished jobs stay downloadable, interrupted ones are failed.
//! Ids are 128 bits from getrandom(2) as 32 lowercase hex digits (the capability to the
//! results); a job belongs to the tenant that submitted it, and is unknown to any other.
class JobStore {
 public:
  //! Called when a job ends (for metrics): scheme, state, seconds running, faces in/out.
  using FinishedFn = std::function<void(const JobView&, double seconds)>;

  //! \throw std::runtime_error when the data directory cannot be created or read, or its
  //! `.tenant-key` is not one this store wrote (see tenant_of()).
  JobStore(JobsConfig config, ComputeSlots& slots, FinishedFn on_finished = {});
  ~JobStore();
  JobStore(const JobStore&) = delete;
  JobStore& operator=(const JobStore&) = delete;

  //! Queues a job owned by `owner` (an opaque tenant id, tenant_of(key); empty when the
  //! daemon has no API keys). Free space is checked first: the data directory's file system
  //! must keep min_free_bytes free after the input, `predicted_result_bytes` (see
  //! predicted_result_bytes()) and the predicted results of every accepted job not yet
  //! finished. The input is written to disk before the job is visible; a write that fails
  //! leaves no job directory behind (NoSpace when it failed for want of space, otherwise
  //! the exception propagates).
  //! `plan` is what the job's runner uses (made with `stl_bytes`; nothing is planned again).
  //! `name`: the uploaded file's name, kept with the job (its downloads are named after it).
  SubmitResult submit(api::RefinePlan plan, std::string query, std::string_view stl_bytes,
                      std::string owner, std::uint64_t predicted_result_bytes,
                      std::string name = {}, std::string callback_url = {});
  //! submit for a request parsed and validated: planned here on `stl_bytes`.
  //! \throw Error(InvalidParameter) when its scheme cannot be made from it.
  SubmitResult submit(api::RefineRequest request, std::string query, std::string_view stl_bytes,
                      std::string owner, std::uint64_t predicted_result_bytes);

  //! Found; Unknown: no such job, or a malformed id, or a job of another owner (the same
  //! answer, `out` untouched); Expired: its results were removed (410); TooLate (cancel
  //! only): the job had finished before the cancel, see cancel().
  enum class Lookup { Found, Unknown, Expired, TooLate };
  //! The job `id` if `owner` owns it (the owner given to submit, compared in constant time).
  Lookup find(const std::string& id, const std::string& owner, JobView* out) const;
  //! Cancels `owner`'s job `id`.
  //!  - Found: it was queued or running, and it ends `cancelled`, never `done`: a queued one
  //!    at once, a running one at its next cancellation check, and one whose computation
  //!    had just ended has its results discarded. `out` is the job as it is now (a running
  //!    one with stage "cancel requested").
  //!  - TooLate: it had already finished (done, failed or cancelled); its results are
  //!    deleted and it then answers 410 (`out`: the finished job, `expired`). Another
  //!    replica's job is deleted by that replica's janitor (within a minute; `out` is the
  //!    job as it was).
  //!  - Expired: its results were already removed. Unknown: as for find().
  Lookup cancel(const std::string& id, const std::string& owner, JobView* out);
  //! The tenant id of an API key: HMAC-SHA256 under this data directory's secret
  //! (`.tenant-key`, 32 random bytes made at the first start, mode 0600, shared by the
  //! replicas of the directory), 32 hex digits. Stable across restarts; the key itself is
  //! never stored.
  std::string tenant_of(std::string_view api_key) const;
  //! Where a page of list() starts: after the job created at created_ms with this id (the
  //! order is newest first, ties by id).
  struct ListCursor {
    std::int64_t created_ms = 0;
    std::string id;
  };
  //! `owner`'s jobs known to this store (submitted here, or found at its start), newest
  //! first, at most `limit` of them after `after`, in `state` when given. `more`: whether
  //! another page follows.
  std::vector<JobView> list(const std::string& owner, std::optional<JobState> state,
                            const std::optional<ListCursor>& after, std::size_t limit,
                            bool* more) const;
  //! A place among the open event streams, held by a stream while it is open (released
  //! when the last copy goes). Empty when `who` holds max_event_streams_per_tenant already
  //! (`*whole` false) or max_event_streams are open (`*whole` true). Its own lock: never
  //! waits for the store's.
  using StreamPlace = std::shared_ptr<void>;
  StreamPlace open_stream(const std::string& who, bool* whole);
  //! find() for a stream polled on the event loop: nullopt instead of waiting when the
  //! store's lock is held (a job being recorded); `*on_disk` when the job is not this
  //! replica's and was read from its job.json.
  std::optional<Lookup> try_find(const std::string& id, const std::string& owner, JobView* out,
                                 bool* on_disk) const;
  //! Path of a result file of a done job (name from JobView::results).
  std::filesystem::path result_path(const std::string& id, const std::string& name) const;

  std::size_t queued() const;
  std::size_t running() const;
  //! Queue mode's figures for /metrics (empty in the embedded mode).
  struct QueueStats {
    bool reachable = false;      //!< the last look at Redis succeeded
    std::uint64_t depth = 0;     //!< jobs no runner has taken yet (every replica's)
    std::uint64_t pending = 0;   //!< jobs taken and not finished (running, or whose runner died)
    std::uint64_t reclaims = 0;  //!< jobs this replica took over from a silent runner
    std::uint64_t attempts = 0;  //!< runs this replica started (first runs and re-runs)
  };
  std::optional<QueueStats> queue_stats() const;
  const JobsConfig& config() const { return config_; }

  //! Stops taking jobs: queued jobs fail ("shutting down"); running jobs may finish until
  //! `grace` has passed, then they are cancelled (503 shutting-down, "cancelled at shutdown
  //! after the grace period"). Returns when every runner has stopped.
  void shutdown(std::chrono::milliseconds grace);
  //! Cancels every running job now (a second SIGTERM): they end cancelled, 503
  //! shutting-down, saying the server was stopped at once.
  void cancel_running();
  //! Removes expired results now (the janitor also does it periodically), with what a crash
  //! left: job directories without job.json and `*.tmp` files untouched for a minute. The
  //! `*.tmp` bytes still there count against disk_budget_bytes.
  void expire_now();

 private:
  struct Job;
  enum class CancelReason { None, Client, ShutdownGrace, ShutdownNow };
  struct Leftovers;
  void run_jobs();
  void run_one(const std::shared_ptr<Job>& job);
  void janitor();
  void persist(const Job& job) const;
  void persist_or_log(const Job& job) const;
  std::shared_ptr<Job> read_job(const std::filesystem::path& dir) const;
  Lookup find_on_disk(const std::string& id, const std::string& owner, JobView* out) const;
  Lookup cancel_on_disk(const std::string& id, const std::string& owner, JobView* out);
  void load_existing();
  Leftovers sweep_leftovers();
  void expire(Job& job);
  JobView view(const Job& job) const;
  void request_cancel(Job& job, CancelReason why);  // under mutex_
  bool cancel_noted(Job& job);                      // another replica's note; takes mutex_
  void cancel_running(CancelReason why);
  void release_disk(Job& job);  // under mutex_
  // Queue mode (queue_store.cpp).
  void start_queue();
  SubmitResult submit_queued(const std::shared_ptr<Job>& job, std::string_view stl_bytes,
                             std::uint64_t predicted_result_bytes);
  Lookup find_queued(const std::string& id, const std::string& owner, JobView* out) const;
  Lookup cancel_queued(const std::string& id, const std::string& owner, JobView* out);
  std::vector<JobView> list_queued(const std::string& owner, std::optional<JobState> state,
                                   const std::optional<ListCursor>& after, std::size_t limit,
                                   bool* more) const;
  void run_queue_jobs();
  void keep_leases();
  void expire_queued();
  void record_queued(const Job& job) const;
  std::optional<Lookup> try_find_queued(const std::string& id, const std::string& owner,
                                        JobView* out, bool* on_disk) const;
  void refresh_watched();
  //! A cancel from another replica, seen just before a runner records the job's end.
  bool cancel_arrived(Job& job);  // under mutex_
  //! Queue mode: a job stopped by a shutdown (before or while it computed) goes back to the
  //! queue for another replica, instead of ending cancelled.
  bool hand_back(Job& job);
  void run_entry(RedisConnection& c, const QueueEntry& entry);
  bool finish_queued(RedisConnection& c, Job& job);
  //! A job's hash (field -> value) from a Job, and back.
  std::map<std::string, std::string> fields_of(const Job& job) const;
  std::shared_ptr<Job> job_of(const std::map<std::string, std::string>& fields) const;
  //! Queues the job's callback, if it has one (it has just ended).
  void notify_ended(const JobView& job);
  api::Problem cancel_problem(CancelReason why, bool discarded) const;
  //! A job that will not run (found unfinished at a start, queued at shutdown) ends now:
  //! cancelled when another replica's cancel was accepted for it, else failed at `stage`
  //! with `failure`.
  void end_unrun(Job& job, const char* stage, const api::Problem& failure) const;

  JobsConfig config_;
  ComputeSlots& slots_;
  FinishedFn on_finished_;
  mutable std::mutex mutex_;
  std::condition_variable work_, janitor_wake_;
  std::map<std::string, std::shared_ptr<Job>> jobs_;
  std::deque<std::shared_ptr<Job>> queue_;
  std::size_t running_ = 0;
  //! Predicted result bytes of accepted, unfinished jobs, and inputs being written.
  std::uint64_t committed_disk_ = 0;
  bool stopping_ = false;
  std::atomic<bool> cancel_all_{false};
  CancelReason shutdown_reason_ = CancelReason::None;  // the cancel_all_ reason
  std::chrono::milliseconds grace_{0};                 // shutdown's, for the message
  std::array<unsigned char, 32> tenant_key_{};
  std::vector<std::thread> runners_;
  std::thread janitor_;
  RequestWatch watch_;                         // deadlines of running jobs
  std::unique_ptr<CallbackSender> callbacks_;  // when callbacks are configured
  std::unique_ptr<RedisQueue> redis_;          // queue mode: where the jobs are
  std::thread keeper_;                         // queue mode: leases, figures, expiry
  struct QueueFigures;
  std::unique_ptr<QueueFigures> figures_;  // queue mode: what keep_leases() last saw
  struct StreamCounts {
    std::mutex mutex;
    std::size_t total = 0;
    std::map<std::string, std::size_t> by_who;
  };
  // Shared with the places handed out: a stream may outlive the store.
  std::shared_ptr<StreamCounts> streams_ = std::make_shared<StreamCounts>();
};

}  // namespace stlrefine::server
