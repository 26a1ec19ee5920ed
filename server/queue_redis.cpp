// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/queue_redis.h"

#include <cstdio>

namespace stlrefine::server {

namespace {

constexpr const char* kStream = "stlrefine:jobs";
constexpr const char* kGroup = "runners";
constexpr const char* kFinished = "stlrefine:finished";

std::string job_key(const std::string& id) {
  return "stlrefine:job:" + id;
}
std::string tenant_key(const std::string& tenant) {
  std::string k = "stlrefine:tenant:";
  k.append(tenant.empty() ? "-" : tenant);  // no API keys: one anonymous tenant
  return k;
}

JobFields to_fields(const RedisReply& flat) {
  JobFields f;
  for (std::size_t i = 0; i + 1 < flat.size(); i += 2) f[flat.at(i).str()] = flat.at(i + 1).str();
  return f;
}

void append_fields(std::vector<std::string>& argv, const JobFields& fields) {
  for (const auto& [k, v] : fields) {
    argv.push_back(k);
    argv.push_back(v);
  }
}

// XREADGROUP / XAUTOCLAIM entries: [[entry-id, [field, value, ...]], ...]; nil fields for
// an entry deleted meanwhile.
std::optional<QueueEntry> first_entry(const RedisReply& entries, bool reclaimed) {
  for (std::size_t i = 0; i < entries.size(); ++i) {
    const RedisReply e = entries.at(i);
    const JobFields f = to_fields(e.at(1));
    const auto it = f.find("id");
    QueueEntry q{e.at(0).str(), it == f.end() ? std::string() : it->second, reclaimed};
    return q;
  }
  return std::nullopt;
}

// Lua: the job's hash and its indexes change in one step, whatever other replicas do.
// The tenant's index also drops its oldest ids whose hash Redis has expired (a finished
// job's TTL, job_key's names): a few per submission, so it holds about the jobs the tenant
// still has instead of every job it ever sent (a listing drops the ones it meets too).
constexpr const char* kEnqueue = R"(
redis.call('HSET', KEYS[1], unpack(ARGV, 3))
for _, old in ipairs(redis.call('ZRANGE', KEYS[2], 0, 7)) do
  if redis.call('EXISTS', 'stlrefine:job:' .. old) == 0 then redis.call('ZREM', KEYS[2], old) end
end
redis.call('ZADD', KEYS[2], ARGV[2], ARGV[1])
redis.call('XADD', KEYS[3], '*', 'id', ARGV[1])
return 1)";

constexpr const char* kStart = R"(
if redis.call('EXISTS', KEYS[1]) == 0 then return {'skip'} end
local state = redis.call('HGET', KEYS[1], 'state')
if state ~= 'queued' and state ~= 'running' then return {'skip'} end
local n = redis.call('HINCRBY', KEYS[1], 'attempts', 1)
if n > tonumber(ARGV[1]) then
  -- Recorded failed by the runner's finish (with its TTL and the expiry index), or, should
  -- that fail, by the runner that takes the entry over next.
  return {'exhausted', redis.call('HGETALL', KEYS[1])}
end
redis.call('HSET', KEYS[1], 'state', 'running', 'stage', 'waiting for a compute slot',
           'worker', ARGV[2], 'heartbeat_ms', ARGV[3], 'sealed', '0', 'progress', '0')
return {'run', redis.call('HGETALL', KEYS[1])})";

constexpr const char* kHeartbeat = R"(
local p = redis.call('XPENDING', KEYS[1], ARGV[1], ARGV[2], ARGV[2], 1)
local owned = 0
if p[1] and p[1][2] == ARGV[3] then
  redis.call('XCLAIM', KEYS[1], ARGV[1], ARGV[3], 0, ARGV[2], 'JUSTID')
  redis.call('HSET', KEYS[2], 'progress', ARGV[4], 'stage', ARGV[5], 'heartbeat_ms', ARGV[6])
  owned = 1
end
local c = 0
if redis.call('HGET', KEYS[2], 'cancel') == '1' then c = 1 end
return {owned, c})";

// Only the runner the job is running on writes its progress (not a stale one whose entry
// was taken over, nor over a final state).
constexpr const char* kRecord = R"(
if redis.call('HGET', KEYS[1], 'state') ~= 'running' then return 0 end
if redis.call('HGET', KEYS[1], 'worker') ~= ARGV[1] then return 0 end
redis.call('HSET', KEYS[1], unpack(ARGV, 2))
return 1)";

constexpr const char* kSeal = R"(
if redis.call('HGET', KEYS[1], 'cancel') == '1' then return 1 end
redis.call('HSET', KEYS[1], 'sealed', '1')
return 0)";

constexpr const char* kFinish = R"(
local p = redis.call('XPENDING', KEYS[3], ARGV[1], ARGV[2], ARGV[2], 1)
if not (p[1] and p[1][2] == ARGV[3]) then return 0 end
redis.call('HSET', KEYS[1], unpack(ARGV, 7))
redis.call('EXPIRE', KEYS[1], ARGV[4])
redis.call('ZADD', KEYS[2], ARGV[5], ARGV[6])
redis.call('XACK', KEYS[3], ARGV[1], ARGV[2])
redis.call('XDEL', KEYS[3], ARGV[2])
return 1)";

// Only while this consumer still owns the entry (as kFinish): a runner whose lease lapsed
// must not take back an entry another replica claimed and runs.
constexpr const char* kHandBack = R"(
local p = redis.call('XPENDING', KEYS[1], ARGV[1], ARGV[2], ARGV[2], 1)
if not (p[1] and p[1][2] == ARGV[4]) then return 0 end
redis.call('XACK', KEYS[1], ARGV[1], ARGV[2])
redis.call('XDEL', KEYS[1], ARGV[2])
if redis.call('EXISTS', KEYS[2]) == 1 then
  redis.call('HSET', KEYS[2], 'state', 'queued', 'stage', 'queued', 'worker', '')
  redis.call('HINCRBY', KEYS[2], 'attempts', -1)
  redis.call('XADD', KEYS[1], '*', 'id', ARGV[3])
end
return 1)";

constexpr const char* kCancel = R"(
if redis.call('EXISTS', KEYS[1]) == 0 then return 'unknown' end
if redis.call('HGET', KEYS[1], 'tenant') ~= ARGV[1] then return 'unknown' end
if redis.call('HGET', KEYS[1], 'expired') == '1' then return 'expired' end
local state = redis.call('HGET', KEYS[1], 'state')
if state == 'queued' then
  redis.call('HSET', KEYS[1], 'state', 'cancelled', 'stage', 'cancelled', 'finished_ms', ARGV[3],
             'problem', ARGV[2], 'cancel', '1')
  redis.call('EXPIRE', KEYS[1], ARGV[4])
  redis.call('ZADD', KEYS[2], ARGV[3], ARGV[5])
  return 'queued'
end
if state == 'running' then
  redis.call('HSET', KEYS[1], 'cancel', '1')
  if redis.call('HGET', KEYS[1], 'sealed') == '1' then return 'finishing' end
  return 'running'
end
redis.call('HSET', KEYS[1], 'expired', '1')
return 'finished')";

// A consumer is deleted only with nothing pending, checked in the same step: DELCONSUMER
// drops a consumer's pending entries, which then no replica could ever reclaim. A live
// replica's next XREADGROUP makes its consumer again, so deleting an idle one is harmless.
constexpr const char* kPruneConsumers = R"(
local removed = 0
for _, c in ipairs(redis.call('XINFO', 'CONSUMERS', KEYS[1], ARGV[1])) do
  local f = {}
  for i = 1, #c, 2 do f[c[i]] = c[i + 1] end
  if f['pending'] == 0 and f['idle'] >= tonumber(ARGV[2]) and f['name'] ~= ARGV[3] then
    redis.call('XGROUP', 'DELCONSUMER', KEYS[1], ARGV[1], f['name'])
    removed = removed + 1
  end
end
return removed)";

constexpr const char* kMarkExpired = R"(
if redis.call('EXISTS', KEYS[1]) == 1 then redis.call('HSET', KEYS[1], 'expired', '1') end
return 1)";

bool no_group(const RedisError& e) {
  return std::string(e.what()).find("NOGROUP") != std::string::npos;
}

}  // namespace

RedisQueue::RedisQueue(RedisAddress address, std::string consumer,
                       std::chrono::milliseconds timeout)
    : consumer_(std::move(consumer)), timeout_(timeout), pool_(std::move(address), timeout) {}

void RedisQueue::ensure_group(RedisConnection& c) const {
  try {
    c.command({"XGROUP", "CREATE", kStream, kGroup, "0", "MKSTREAM"});
  } catch (const RedisError& e) {
    if (std::string(e.what()).find("BUSYGROUP") == std::string::npos) throw;
  }
}

void RedisQueue::enqueue(RedisConnection& c, const std::string& id, const std::string& tenant,
                         std::int64_t created_ms, const JobFields& fields) const {
  std::vector<std::string> argv{"EVAL",
                                kEnqueue,
                                "3",
                                job_key(id),
                                tenant_key(tenant),
                                kStream,
                                id,
                                std::to_string(created_ms)};
  append_fields(argv, fields);
  c.command(argv);
}

std::optional<QueueEntry> RedisQueue::reclaim(RedisConnection& c,
                                              std::chrono::milliseconds lease) const {
  // XAUTOCLAIM scans the pending entries from a cursor; follow it a few pages so an idle
  // entry behind many live ones is found too.
  std::string cursor = "0-0";
  for (int page = 0; page < 20; ++page) {
    const RedisReply r = c.command({"XAUTOCLAIM", kStream, kGroup, consumer_,
                                    std::to_string(lease.count()), cursor, "COUNT", "1"});
    if (std::optional<QueueEntry> e = first_entry(r.at(1), true)) return e;
    cursor = r.at(0).str();
    if (cursor == "0-0") break;
  }
  return std::nullopt;
}

std::optional<QueueEntry> RedisQueue::next(RedisConnection& c,
                                           std::chrono::milliseconds block) const {
  RedisReply r;
  try {
    r = c.command({"XREADGROUP", "GROUP", kGroup, consumer_, "COUNT", "1", "BLOCK",
                   std::to_string(block.count()), "STREAMS", kStream, ">"},
                  block);
  } catch (const RedisError& e) {
    // The group went away (a Redis restarted without its data): make it again.
    if (!no_group(e)) throw;
    ensure_group(c);
    return std::nullopt;
  }
  if (r.nil()) return std::nullopt;  // nothing within `block`
  return first_entry(r.at(0).at(1), false);
}

RedisQueue::Start RedisQueue::start(RedisConnection& c, const std::string& id, int max_attempts,
                                    const std::string& exhausted_problem,
                                    std::int64_t now_ms) const {
  const RedisReply r = c.command({"EVAL", kStart, "1", job_key(id), std::to_string(max_attempts),
                                  consumer_, std::to_string(now_ms), exhausted_problem});
  Start s;
  const std::string kind = r.at(0).str();
  s.kind = kind == "run"         ? Start::Kind::Run
           : kind == "exhausted" ? Start::Kind::Exhausted
                                 : Start::Kind::Skip;
  if (s.kind != Start::Kind::Skip) s.fields = to_fields(r.at(1));
  return s;
}

RedisQueue::Beat RedisQueue::heartbeat(RedisConnection& c, const std::string& id,
                                       const std::string& entry, double progress,
                                       const std::string& stage, std::int64_t now_ms) const {
  char p[32];
  std::snprintf(p, sizeof p, "%.6g", progress);
  const RedisReply r = c.command({"EVAL", kHeartbeat, "2", kStream, job_key(id), kGroup, entry,
                                  consumer_, p, stage, std::to_string(now_ms)});
  return {r.at(0).integer() == 1, r.at(1).integer() == 1};
}

void RedisQueue::record(RedisConnection& c, const std::string& id, const JobFields& fields) const {
  std::vector<std::string> argv{"EVAL", kRecord, "1", job_key(id), consumer_};
  append_fields(argv, fields);
  c.command(argv);
}

bool RedisQueue::seal(RedisConnection& c, const std::string& id) const {
  return c.command({"EVAL", kSeal, "1", job_key(id)}).integer() == 1;
}

bool RedisQueue::finish(RedisConnection& c, const std::string& id, const std::string& entry,
                        const JobFields& fields, std::chrono::seconds keep,
                        std::int64_t finished_ms) const {
  std::vector<std::string> argv{"EVAL",
                                kFinish,
                                "3",
                                job_key(id),
                                kFinished,
                                kStream,
                                kGroup,
                                entry,
                                consumer_,
                                std::to_string(keep.count()),
                                std::to_string(finished_ms),
                                id};
  append_fields(argv, fields);
  return c.command(argv).integer() == 1;
}

void RedisQueue::drop(RedisConnection& c, const std::string& entry) const {
  c.pipeline({{"XACK", kStream, kGroup, entry}, {"XDEL", kStream, entry}});
}

bool RedisQueue::hand_back(RedisConnection& c, const std::string& id,
                           const std::string& entry) const {
  return c.command({"EVAL", kHandBack, "2", kStream, job_key(id), kGroup, entry, id, consumer_})
             .integer() == 1;
}

std::optional<JobFields> RedisQueue::load(RedisConnection& c, const std::string& id) const {
  const RedisReply r = c.command({"HGETALL", job_key(id)});
  if (r.size() == 0) return std::nullopt;
  return to_fields(r);
}

std::vector<std::optional<JobFields>> RedisQueue::load_many(
    RedisConnection& c, const std::vector<std::string>& ids) const {
  std::vector<std::vector<std::string>> commands;
  for (const std::string& id : ids) commands.push_back({"HGETALL", job_key(id)});
  std::vector<std::optional<JobFields>> out;
  if (commands.empty()) return out;
  for (const RedisReply& r : c.pipeline(commands))
    out.push_back(r.size() == 0 ? std::nullopt : std::optional<JobFields>(to_fields(r)));
  return out;
}

RedisQueue::Cancel RedisQueue::cancel(RedisConnection& c, const std::string& id,
                                      const std::string& owner,
                                      const std::string& cancelled_problem, std::int64_t now_ms,
                                      std::chrono::seconds keep) const {
  const std::string r =
      c.command({"EVAL", kCancel, "2", job_key(id), kFinished, owner, cancelled_problem,
                 std::to_string(now_ms), std::to_string(keep.count()), id})
          .str();
  return r == "expired"     ? Cancel::Expired
         : r == "queued"    ? Cancel::Queued
         : r == "running"   ? Cancel::Running
         : r == "finishing" ? Cancel::Finishing
         : r == "finished"  ? Cancel::Finished
                            : Cancel::Unknown;
}

void RedisQueue::mark_expired(RedisConnection& c, const std::string& id) const {
  c.command({"EVAL", kMarkExpired, "1", job_key(id)});
}

std::vector<std::pair<std::int64_t, std::string>> RedisQueue::tenant_jobs(
    RedisConnection& c, const std::string& owner, std::int64_t max_ms, std::size_t count,
    std::size_t offset) const {
  const RedisReply r =
      c.command({"ZREVRANGEBYSCORE", tenant_key(owner), std::to_string(max_ms), "-inf",
                 "WITHSCORES", "LIMIT", std::to_string(offset), std::to_string(count)});
  std::vector<std::pair<std::int64_t, std::string>> out;
  for (std::size_t i = 0; i + 1 < r.size(); i += 2)
    out.emplace_back(r.at(i + 1).integer(), r.at(i).str());
  return out;
}

void RedisQueue::forget(RedisConnection& c, const std::string& owner,
                        const std::vector<std::string>& ids) const {
  if (ids.empty()) return;
  std::vector<std::string> argv{"ZREM", tenant_key(owner)};
  argv.insert(argv.end(), ids.begin(), ids.end());
  c.command(argv);
}

RedisQueue::Stats RedisQueue::stats(RedisConnection& c) const {
  // Entries are deleted once finished: the stream holds the waiting and the taken ones.
  auto read = [&] { return c.pipeline({{"XLEN", kStream}, {"XPENDING", kStream, kGroup}}); };
  std::vector<RedisReply> r;
  try {
    r = read();
  } catch (const RedisError& e) {
    // No group yet (a Redis restarted without its data, or one that was full when this
    // replica started): make it, which a full Redis refuses with OOM (a 503, not a 500).
    if (!no_group(e)) throw;
    ensure_group(c);
    r = read();
  }
  Stats s;
  s.pending = r[1].at(0).integer();
  s.depth = std::max(0LL, r[0].integer() - s.pending);
  return s;
}

std::vector<std::string> RedisQueue::due(RedisConnection& c, std::int64_t before_ms,
                                         std::size_t count) const {
  const RedisReply r = c.command({"ZRANGEBYSCORE", kFinished, "-inf", std::to_string(before_ms),
                                  "LIMIT", "0", std::to_string(count)});
  std::vector<std::string> out;
  for (std::size_t i = 0; i < r.size(); ++i) out.push_back(r.at(i).str());
  return out;
}

void RedisQueue::expired(RedisConnection& c, const std::string& id) const {
  c.command({"ZREM", kFinished, id});
}

long long RedisQueue::prune_consumers(RedisConnection& c, std::chrono::milliseconds idle) const {
  try {
    return c
        .command({"EVAL", kPruneConsumers, "1", kStream, kGroup, std::to_string(idle.count()),
                  consumer_})
        .integer();
  } catch (const RedisError& e) {
    if (!no_group(e)) throw;
    return 0;  // no group yet: no consumer either
  }
}

}  // namespace stlrefine::server
