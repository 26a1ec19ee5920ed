// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Inside the job store (jobs.h), shared by its files: a job as the store keeps it, and the
// data directory's files (ids, atomic writes, a crash's leftovers, directory locks, the
// tenant secret). job_store.cpp queues, finds and cancels jobs; job_runner.cpp runs them;
// job_disk.cpp records them on disk, recovers them at a start and expires them; job_view.cpp
// is what a client sees of one. Not part of the server's interface.

#include <sys/types.h>

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <string_view>
#include <system_error>

#include "api/plan.h"
#include "api/problem.h"
#include "core/io/atomic_file.h"
#include "server/jobs.h"
#include "server/queue_redis.h"

namespace stlrefine::server {

struct JobStore::Job {
  std::string id;
  std::string instance;  // the replica running it (JobsConfig::instance); "owner" on disk
  std::string tenant;    // who may see it (submit's owner); "tenant" on disk
  std::filesystem::path dir;
  //! Made at submit, and what the runner uses. Empty for a job read from disk at a start
  //! (such a job is never run: an unfinished one is failed).
  api::RefinePlan plan;
  std::string scheme, query;
  std::string name;          // the uploaded file's name (sanitised; may be empty); "name" on disk
  std::string callback_url;  // "callback_url" on disk
  JobState state = JobState::Queued;
  bool expired = false;
  std::atomic<bool> cancel{false};
  double progress = 0;
  std::string stage = "queued";
  std::chrono::system_clock::time_point created, started, finished;
  nlohmann::ordered_json report = nlohmann::ordered_json::object();
  std::optional<nlohmann::ordered_json> problem;
  std::vector<std::string> results;
  std::uint64_t result_bytes = 0;
  //! Its share of committed_disk_ (its predicted results) until it finishes.
  std::uint64_t reserved_disk = 0;
  //! Who cancelled it first (under the mutex; `cancel` is raised with it).
  CancelReason cancel_reason = CancelReason::None;
  //! While it computes: its cancel flag (deadline, DELETE, shutdown). Under the mutex.
  std::shared_ptr<RequestWatch::Ticket> ticket;
  // Queue mode.
  std::string entry;         // its stream entry while this replica runs it
  bool handed_back = false;  // put back in the queue by a shutdown (hand_back)
  bool superseded = false;   // another replica took its entry over (this lease lapsed)
};

//! Queue mode: the figures of /metrics and the jobs event streams follow, refreshed by the
//! lease keeper (the event loop never waits for Redis).
struct JobStore::QueueFigures {
  std::atomic<bool> reachable{false};
  std::atomic<std::uint64_t> depth{0}, pending{0}, reclaims{0}, attempts{0};
  //! The jobs event streams follow (key: id and owner), as the keeper last read them: a
  //! stream polls on the event loop, which never waits for Redis.
  struct Watched {
    std::optional<Lookup> found;  // empty until first read
    JobView view;
    std::chrono::steady_clock::time_point asked;
  };
  std::mutex watch_mutex;
  std::map<std::pair<std::string, std::string>, Watched> watched;
};

struct JobStore::Leftovers {
  std::uint64_t tmp_bytes = 0;         // *.tmp files of this store's jobs still there
  std::vector<std::string> to_delete;  // this store's jobs another replica deleted
};

namespace job_files {

using Clock = std::chrono::system_clock;

inline constexpr const char* kJobFile = "job.json";
inline constexpr const char* kInputFile = "input.stl";
//! How long a running job waits for memory its refinement needs next (held by other work).
inline constexpr std::chrono::seconds kGrowWait{10};
//! Notes from another replica sharing the data directory, for the job's owner: cancel it
//! (running), delete its results (finished).
inline constexpr const char* kCancelFile = "cancel";
inline constexpr const char* kDeleteFile = "delete";
inline constexpr const char* kTenantKeyFile = ".tenant-key";
inline constexpr std::size_t kTenantKeyBytes = 32;
//! A job directory without job.json, or a *.tmp file, untouched this long is what a crash
//! (or SIGKILL) left in the middle of a write.
inline constexpr auto kLeftoverAge = std::chrono::seconds(60);

//! A job stopped by the memory budget while other work held it (admission never answers
//! it: a job waits for its reservation).
api::Problem job_busy_problem(std::uint64_t needed);
//! The 507 of a job whose results could not be written for want of space.
api::Problem no_space_result_problem();

JobState state_from(const std::string& s);
bool finished(JobState s);
[[noreturn]] void throw_errno(int err, const std::string& what);
std::string hex(const unsigned char* bytes, std::size_t size);
//! 128 bits from the OS as 32 lowercase hex digits: ids are capabilities for the results.
std::string new_job_id();
//! Only ids this store could have made: no path can be smuggled into the data directory.
bool well_formed_id(const std::string& id);
//! Owners compared without an early exit.
bool same_tenant(const std::string& a, const std::string& b);
//! A write that failed for want of space (the device, a quota, a file size limit).
bool no_space(const std::error_code& ec);
std::uint64_t saturating_add(std::uint64_t a, std::uint64_t b);
std::uint64_t statvfs_free(const std::filesystem::path& dir);
std::int64_t epoch_ms(Clock::time_point t);
Clock::time_point from_epoch_ms(std::int64_t ms);
std::string iso8601(Clock::time_point t);

//! The core's atomic writer with the temporary name ".<name>.tmp", which the janitor knows
//! as a crash's leftover; its failures come out as std::system_error with the system's code.
void write_atomically(const std::filesystem::path& path,
                      const std::function<void(const ByteSink&)>& produce, mode_t mode = 0644);
void write_atomically(const std::filesystem::path& path, std::string_view bytes,
                      mode_t mode = 0644);
bool is_tmp(const std::filesystem::path& path);
//! Untouched (the entry and, for a directory, its entries) for kLeftoverAge.
bool left_over(const std::filesystem::path& path, std::filesystem::file_time_type now);

//! An exclusive flock(2) on a job's directory, held while the owner writes a job's final
//! state and while another replica reads it to leave a cancel note: the note arrives before
//! the final state (and the job is cancelled) or the replica sees the job finished. Best
//! effort: where directories cannot be locked, nothing is.
class DirLock {
 public:
  explicit DirLock(const std::filesystem::path& dir);
  ~DirLock();
  DirLock(const DirLock&) = delete;
  DirLock& operator=(const DirLock&) = delete;

 private:
  int fd_;
};

//! The data directory's tenant secret, read or made (first start).
std::array<unsigned char, kTenantKeyBytes> load_tenant_key(const std::filesystem::path& data_dir);
std::string read_file(const std::filesystem::path& path);
//! A tenant id: HMAC-SHA256 of the API key under the data directory's secret, 32 hex digits
//! (server/job_callback_keys.cpp).
std::string tenant_id(const std::array<unsigned char, kTenantKeyBytes>& tenant_key,
                      std::string_view api_key);
//! The refined mesh's file: result.3mf for mesh_format=3mf (its objects and unit kept), else
//! result.stl.
inline const char* job_result_name(const api::RefineRequest& request) {
  return request.mesh_format == MeshFormat::ThreeMf ? "result.3mf" : "result.stl";
}
//! "stlrefined: <line>" on stderr in one write.
void log_line(const std::string& line);

}  // namespace job_files
}  // namespace stlrefine::server
