// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
// What the job store offers event streams (server/job_events.cpp), which run on the front
// end's event loop: a bounded number of places, and a look at a job that never waits for
// the store's lock (held while a job's record is written to disk).
#include "server/job_record.h"

namespace stlrefine::server {

using namespace job_files;

JobStore::StreamPlace JobStore::open_stream(const std::string& who, bool* whole) {
  StreamCounts& c = *streams_;
  std::lock_guard lock(c.mutex);
  *whole = c.total >= config_.max_event_streams;
  if (*whole) return nullptr;
  std::size_t& mine = c.by_who[who];
  if (mine >= config_.max_event_streams_per_tenant) {
    if (mine == 0) c.by_who.erase(who);
    return nullptr;
  }
  ++mine;
  ++c.total;
  // The place is a token whose deleter gives it back (not null: an empty pointer would read
  // as no place).
  return std::shared_ptr<void>(streams_.get(), [counts = streams_, who](void*) {
    std::lock_guard lock(counts->mutex);
    --counts->total;
    const auto it = counts->by_who.find(who);
    if (it != counts->by_who.end() && --it->second == 0) counts->by_who.erase(it);
  });
}

std::optional<JobStore::Lookup> JobStore::try_find(const std::string& id, const std::string& owner,
                                                   JobView* out, bool* on_disk) const {
  *on_disk = false;
  if (!well_formed_id(id)) return Lookup::Unknown;
  if (redis_) return try_find_queued(id, owner, out, on_disk);  // queue_store.cpp
  {
    std::unique_lock lock(mutex_, std::try_to_lock);
    if (!lock.owns_lock()) return std::nullopt;
    const auto it = jobs_.find(id);
    if (it != jobs_.end()) {
      const Job& job = *it->second;
      if (!same_tenant(job.tenant, owner)) return Lookup::Unknown;
      if (out) *out = view(job);
      return job.expired ? Lookup::Expired : Lookup::Found;
    }
  }
  *on_disk = true;
  return find_on_disk(id, owner, out);
}

}  // namespace stlrefine::server
