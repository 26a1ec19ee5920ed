// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// The Redis side of the job store's queue mode (issue 20): which keys hold what, and each
// change of a job's state as one atomic step (a Lua script or one command).
//
//  stlrefine:jobs            stream of {id}; consumer group "runners" (every replica's runners)
//  stlrefine:job:{id}        hash: the job (state, progress, stage, timings, report, problem,
//                            results, tenant, worker, attempts, cancel); TTL once finished
//  stlrefine:tenant:{t}      sorted set: the tenant's job ids by created_ms (GET /v1/jobs)
//  stlrefine:finished        sorted set: finished job ids by finished_ms (result expiry)
//
// A runner's entry stays pending in the group while it computes; its heartbeat resets the
// entry's idle time, and an entry idle for a lease is claimed (XAUTOCLAIM) by another runner.

#include <chrono>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "server/redis_client.h"

namespace stlrefine::server {

//! A job as its hash holds it: field -> value, all strings.
using JobFields = std::map<std::string, std::string>;

//! A stream entry a runner took: its entry id and the job's id.
struct QueueEntry {
  std::string entry;
  std::string job;
  bool reclaimed = false;  //!< taken over from a silent runner (XAUTOCLAIM)
};

class RedisQueue {
 public:
  RedisQueue(RedisAddress address, std::string consumer, std::chrono::milliseconds timeout);

  //! This replica's name in the consumer group (and a job's `worker`).
  const std::string& consumer() const { return consumer_; }
  //! Connections for HTTP threads.
  RedisPool& pool() { return pool_; }
  std::chrono::milliseconds timeout() const { return timeout_; }

  //! The stream and its group, made if missing (a fresh Redis, or one restarted without AOF).
  void ensure_group(RedisConnection& c) const;
  //! The job's hash and tenant index, and its stream entry, in one step.
  void enqueue(RedisConnection& c, const std::string& id, const std::string& tenant,
               std::int64_t created_ms, const JobFields& fields) const;
  //! An entry whose runner has been silent for `lease`, now this consumer's.
  std::optional<QueueEntry> reclaim(RedisConnection& c, std::chrono::milliseconds lease) const;
  //! The next new entry, waiting up to `block` for one.
  std::optional<QueueEntry> next(RedisConnection& c, std::chrono::milliseconds block) const;

  struct Start {
    enum class Kind { Run, Skip, Exhausted } kind = Kind::Skip;
    JobFields fields;  //!< Run: the job, now running here; Exhausted: failed now
  };
  //! Counts an attempt and marks the job running here. Skip: it has ended or is gone (the
  //! entry is only to be acknowledged); Exhausted: more than `max_attempts`, to be recorded
  //! failed (finish) with `exhausted_problem` by the caller.
  Start start(RedisConnection& c, const std::string& id, int max_attempts,
              const std::string& exhausted_problem, std::int64_t now_ms) const;

  struct Beat {
    bool owned = false;   //!< the entry is still this consumer's (its lease renewed)
    bool cancel = false;  //!< a cancel was asked (from any replica)
  };
  //! Renews a running job's lease and publishes its progress (only while it owns the entry).
  Beat heartbeat(RedisConnection& c, const std::string& id, const std::string& entry,
                 double progress, const std::string& stage, std::int64_t now_ms) const;
  //! Some fields of a job running on this consumer (else nothing).
  void record(RedisConnection& c, const std::string& id, const JobFields& fields) const;
  //! Before a runner records a final state: true when a cancel had arrived; from here a
  //! cancel sees the job finishing.
  bool seal(RedisConnection& c, const std::string& id) const;
  //! The final state: fields, the TTL (`keep`), the expiry index, the entry acknowledged and
  //! deleted. Only while this consumer still owns `entry` (else false: another took it over).
  bool finish(RedisConnection& c, const std::string& id, const std::string& entry,
              const JobFields& fields, std::chrono::seconds keep, std::int64_t finished_ms) const;
  //! Acknowledges and deletes an entry with nothing to run.
  void drop(RedisConnection& c, const std::string& entry) const;
  //! An unstarted job back at the end of the queue (shutdown): a new entry, the attempt
  //! not counted. Only while this consumer still owns `entry` (else false, nothing done).
  bool hand_back(RedisConnection& c, const std::string& id, const std::string& entry) const;

  std::optional<JobFields> load(RedisConnection& c, const std::string& id) const;
  std::vector<std::optional<JobFields>> load_many(RedisConnection& c,
                                                  const std::vector<std::string>& ids) const;

  enum class Cancel { Unknown, Expired, Queued, Running, Finishing, Finished };
  //! DELETE: Queued: it was cancelled now (`cancelled_problem`); Running: its flag is set;
  //! Finishing: its runner is recording its end; Finished: it had ended, now marked expired.
  Cancel cancel(RedisConnection& c, const std::string& id, const std::string& owner,
                const std::string& cancelled_problem, std::int64_t now_ms,
                std::chrono::seconds keep) const;
  //! Marks a finished job's results removed (410 from now on).
  void mark_expired(RedisConnection& c, const std::string& id) const;

  //! (created_ms, id) of `owner`'s jobs, newest first, created at or before `max_ms`: `count`
  //! of them after the first `offset`.
  std::vector<std::pair<std::int64_t, std::string>> tenant_jobs(RedisConnection& c,
                                                                const std::string& owner,
                                                                std::int64_t max_ms,
                                                                std::size_t count,
                                                                std::size_t offset = 0) const;
  //! Removes ids whose hash has expired from `owner`'s index.
  void forget(RedisConnection& c, const std::string& owner,
              const std::vector<std::string>& ids) const;

  struct Stats {
    long long depth = 0;    //!< entries no runner has taken yet
    long long pending = 0;  //!< entries taken and not finished (running, or silent)
  };
  Stats stats(RedisConnection& c) const;
  //! Finished jobs that ended at or before `before_ms` (their results are due to expire).
  std::vector<std::string> due(RedisConnection& c, std::int64_t before_ms, std::size_t count) const;
  //! Takes `id` off the expiry index.
  void expired(RedisConnection& c, const std::string& id) const;
  //! Deletes the group's consumers (other than this one) idle for `idle` with nothing
  //! pending: those of replicas that stopped or restarted under a new name. Returns how many.
  long long prune_consumers(RedisConnection& c, std::chrono::milliseconds idle) const;

 private:
  std::string consumer_;
  std::chrono::milliseconds timeout_;
  RedisPool pool_;
};

}  // namespace stlrefine::server
