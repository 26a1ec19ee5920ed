// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

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
#include <thread>
#include <vector>

#include "api/params.h"
#include "api/problem.h"
#include "server/compute_slots.h"
#include "server/memory_budget.h"
#include "server/request_watch.h"

namespace stlrefine::server {

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
};

//! What a client sees of a job (a copy, taken under the store's lock).
struct JobView {
  std::string id;
  JobState state = JobState::Queued;
  bool expired = false;  //!< results removed after retention (410)
  double progress = 0;   //!< [0, 1]
  std::string stage;     //!< "queued", "level 2/3", "slicing", "done", ...
  std::string scheme;
  std::string query;  //!< the parameters as submitted
  std::chrono::system_clock::time_point created, started, finished;
  nlohmann::ordered_json report;                  //!< the refine report once done
  std::optional<nlohmann::ordered_json> problem;  //!< RFC 9457 body once failed/cancelled
  std::vector<std::string> results;               //!< file names ready for download
};

//! The job's JSON answer: id, state, progress, stage, timings, report, problem, links.
nlohmann::ordered_json job_json(const JobView& job);

//! Asynchronous refinement jobs (refine, optionally slice) with a bounded queue, results in
//! a data directory written by atomic rename, retention by age and disk budget, and
//! recovery after a restart: finished jobs stay downloadable, interrupted ones are failed.
class JobStore {
 public:
  //! Called when a job ends (for metrics): scheme, state, seconds running, faces in/out.
  using FinishedFn = std::function<void(const JobView&, double seconds)>;

  //! \throw std::runtime_error when the data directory cannot be created or read.
  JobStore(JobsConfig config, ComputeSlots& slots, FinishedFn on_finished = {});
  ~JobStore();
  JobStore(const JobStore&) = delete;
  JobStore& operator=(const JobStore&) = delete;

  //! Queues a job; its input is written to disk first. Returns nothing when the queue is
  //! full or the store is shutting down.
  std::optional<JobView> submit(api::RefineRequest request, std::string query,
                                std::string_view stl_bytes);

  enum class Lookup { Found, Unknown, Expired };
  Lookup find(const std::string& id, JobView* out) const;
  //! Cancels a queued or running job (a running one stops at its next cancellation check);
  //! a finished job's results are deleted (it then answers 410).
  Lookup cancel(const std::string& id, JobView* out);
  //! Path of a result file of a done job (name from JobView::results).
  std::filesystem::path result_path(const std::string& id, const std::string& name) const;

  std::size_t queued() const;
  std::size_t running() const;
  const JobsConfig& config() const { return config_; }

  //! Stops taking jobs: queued jobs fail ("shutting down"); running jobs may finish until
  //! `grace` has passed, then they are cancelled. Returns when every runner has stopped.
  void shutdown(std::chrono::milliseconds grace);
  //! Cancels every running job now (a second SIGTERM).
  void cancel_running();
  //! Removes expired results now (the janitor also does it periodically).
  void expire_now();

 private:
  struct Job;
  void run_jobs();
  void run_one(const std::shared_ptr<Job>& job);
  void janitor();
  void persist(const Job& job) const;
  void persist_or_log(const Job& job) const;
  std::shared_ptr<Job> read_job(const std::filesystem::path& dir) const;
  Lookup find_on_disk(const std::string& id, JobView* out) const;
  void load_existing();
  void expire(Job& job);
  JobView view(const Job& job) const;

  JobsConfig config_;
  ComputeSlots& slots_;
  FinishedFn on_finished_;
  mutable std::mutex mutex_;
  std::condition_variable work_, janitor_wake_;
  std::map<std::string, std::shared_ptr<Job>> jobs_;
  std::deque<std::shared_ptr<Job>> queue_;
  std::size_t running_ = 0;
  bool stopping_ = false;
  std::atomic<bool> cancel_all_{false};
  std::vector<std::thread> runners_;
  std::thread janitor_;
  RequestWatch watch_;  // deadlines of running jobs
};

}  // namespace stlrefine::server
