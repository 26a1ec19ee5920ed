// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
// The job store's records on disk: job.json written and read, the jobs found at a start
// (interrupted ones failed), and results expired by age and disk budget with what a crash
// left behind.
#include <algorithm>
#include <nlohmann/json.hpp>
#include <set>

#include "server/job_record.h"

namespace stlrefine::server {

namespace fs = std::filesystem;
using namespace job_files;

std::shared_ptr<JobStore::Job> JobStore::read_job(const fs::path& dir) const {
  const auto j = nlohmann::json::parse(read_file(dir / kJobFile));
  auto job = std::make_shared<Job>();
  job->id = dir.filename().string();
  job->dir = dir;
  job->instance = j.value("owner", "");
  job->tenant = j.value("tenant", "");
  job->state = state_from(j.at("state").get<std::string>());
  job->expired = j.value("expired", false);
  job->scheme = j.value("scheme", "");
  job->query = j.value("parameters", "");
  job->name = j.value("name", "");
  job->callback_url = j.value("callback_url", "");
  job->progress = j.value("progress", 0.0);
  job->stage = j.value("stage", "");
  job->created = from_epoch_ms(j.value("created_ms", std::int64_t{0}));
  job->started = from_epoch_ms(j.value("started_ms", std::int64_t{0}));
  job->finished = from_epoch_ms(j.value("finished_ms", std::int64_t{0}));
  if (j.contains("report")) job->report = j["report"];
  if (j.contains("problem")) job->problem = j["problem"];
  job->results = j.value("results", std::vector<std::string>{});
  job->result_bytes = j.value("result_bytes", std::uint64_t{0});
  return job;
}

void JobStore::load_existing() {
  // Before the runners and the janitor start: nothing of this instance is being written.
  const auto now = fs::file_time_type::clock::now();
  for (const fs::directory_entry& entry : fs::directory_iterator(config_.data_dir)) {
    const std::string id = entry.path().filename().string();
    std::error_code ec;
    // Only what this store writes is cleaned: never through a symbolic link.
    const bool link = entry.is_symlink(ec);
    if (is_tmp(entry.path()) && !link && !entry.is_directory(ec) && left_over(entry.path(), now)) {
      fs::remove(entry.path(), ec);  // e.g. a tenant secret half made
      continue;
    }
    if (!entry.is_directory() || !well_formed_id(id)) continue;
    std::shared_ptr<Job> job;
    try {
      job = read_job(entry.path());
    } catch (const std::exception& e) {
      // A job directory without a (valid) job.json: what a crash or a full disk left
      // between creating it and its first job.json. Removed once nobody can be writing it.
      if (!link && left_over(entry.path(), now)) {
        log_line("removing partial job directory " + entry.path().string() + " (" + e.what() + ")");
        fs::remove_all(entry.path(), ec);
      } else {
        log_line("skipping job directory " + entry.path().string() + ": " + e.what());
      }
      continue;
    }
    // Another replica's job (a shared data volume): it is read from disk when asked for.
    const bool ours = job->instance.empty() || job->instance == config_.instance;
    // Temporary files of a write a SIGKILL interrupted: all of ours, others' once stale.
    if (!link)
      for (const fs::directory_entry& file : fs::directory_iterator(entry.path(), ec))
        if (is_tmp(file.path()) && (ours || left_over(file.path(), now))) {
          log_line("removing " + file.path().string() + " (an interrupted write)");
          fs::remove(file.path(), ec);
        }
    if (!ours) continue;
    try {
      if (!finished(job->state)) {
        // It was queued or running when this daemon stopped: say so, never drop it silently
        // (cancelled, if another replica's cancel was accepted for it).
        end_unrun(
            *job, "interrupted",
            api::server_error("interrupted",
                              "the daemon stopped before this job finished; submit it again"));
        // Its input, and results it wrote before job.json could list them.
        if (!link)
          for (const fs::directory_entry& file : fs::directory_iterator(job->dir, ec))
            if (file.path().filename() != kJobFile) fs::remove_all(file.path(), ec);
        job->results.clear();
        job->result_bytes = 0;
        persist(*job);
      }
      jobs_.emplace(id, std::move(job));
    } catch (const std::exception& e) {
      log_line("skipping job directory " + entry.path().string() + ": " + e.what());
    }
  }
}

void JobStore::persist(const Job& job) const {
  if (redis_) return record_queued(job);  // queue_store.cpp
  nlohmann::ordered_json j;
  j["id"] = job.id;
  j["owner"] = job.instance;
  j["tenant"] = job.tenant;
  j["state"] = to_string(job.state);
  j["expired"] = job.expired;
  j["scheme"] = job.scheme;
  j["parameters"] = job.query;
  if (!job.name.empty()) j["name"] = job.name;
  if (!job.callback_url.empty()) j["callback_url"] = job.callback_url;
  j["progress"] = job.progress;
  j["stage"] = job.stage;
  j["created_ms"] = epoch_ms(job.created);
  j["started_ms"] = epoch_ms(job.started);
  j["finished_ms"] = epoch_ms(job.finished);
  if (!job.report.empty()) j["report"] = job.report;
  if (job.problem) j["problem"] = *job.problem;
  j["results"] = job.results;
  j["result_bytes"] = job.result_bytes;
  write_atomically(job.dir / kJobFile,
                   j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n");
}

void JobStore::persist_or_log(const Job& job) const {
  // On a runner thread nothing may escape: a data directory removed or full under a
  // running job costs that job's record on disk, not the daemon.
  try {
    persist(job);
  } catch (const std::exception& e) {
    log_line("job " + job.id + ": cannot record its state: " + e.what());
  }
}

void JobStore::expire(Job& job) {
  std::error_code ignored;
  for (const std::string& name : job.results) fs::remove(job.dir / name, ignored);
  job.expired = true;
  job.result_bytes = 0;
  persist_or_log(job);
}

JobStore::Leftovers JobStore::sweep_leftovers() {
  // Without the lock (it reads the whole data directory): what this store knows is copied.
  std::set<std::string> ours;
  {
    std::lock_guard lock(mutex_);
    for (const auto& [id, job] : jobs_) ours.insert(id);
  }
  Leftovers found;
  const auto now = fs::file_time_type::clock::now();
  std::error_code ec;
  for (const fs::directory_entry& entry : fs::directory_iterator(config_.data_dir, ec)) {
    const std::string id = entry.path().filename().string();
    std::error_code e;
    if (entry.is_symlink(e)) continue;  // not written by a store
    if (!entry.is_directory(e)) {
      if (is_tmp(entry.path()) && left_over(entry.path(), now)) fs::remove(entry.path(), e);
      continue;
    }
    if (!well_formed_id(id)) continue;
    const bool own = ours.count(id) != 0;
    if (!own && !fs::exists(entry.path() / kJobFile, e)) {
      // Partial (a crash between mkdir and job.json), of any replica.
      if (left_over(entry.path(), now)) {
        log_line("removing partial job directory " + entry.path().string());
        fs::remove_all(entry.path(), e);
      }
      continue;
    }
    for (const fs::directory_entry& file : fs::directory_iterator(entry.path(), e)) {
      if (!is_tmp(file.path())) continue;
      if (left_over(file.path(), now)) {
        log_line("removing " + file.path().string() + " (an interrupted write)");
        fs::remove(file.path(), e);
      } else if (own) {
        const std::uint64_t size = file.file_size(e);
        if (!e) found.tmp_bytes += size;
      }
    }
    if (own && fs::exists(entry.path() / kDeleteFile, e)) found.to_delete.push_back(id);
  }
  return found;
}

void JobStore::expire_now() {
  if (redis_) return expire_queued();
  const Leftovers leftovers = sweep_leftovers();
  std::lock_guard lock(mutex_);
  for (const std::string& id : leftovers.to_delete) {
    const auto it = jobs_.find(id);
    if (it == jobs_.end() || !finished(it->second->state)) continue;
    if (!it->second->expired) expire(*it->second);  // DELETE through another replica
    std::error_code ignored;
    fs::remove(it->second->dir / kDeleteFile, ignored);
  }
  const auto now = Clock::now();
  std::vector<Job*> kept;
  std::uint64_t total = leftovers.tmp_bytes;  // interrupted writes take disk space too
  for (auto it = jobs_.begin(); it != jobs_.end();) {
    Job& job = *it->second;
    if (!finished(job.state)) {
      ++it;
      continue;
    }
    if (job.expired) {
      // The tombstone answers 410 for another retention period, then the id is forgotten.
      if (job.finished + 2 * config_.retention < now) {
        std::error_code ignored;
        fs::remove_all(job.dir, ignored);
        it = jobs_.erase(it);
        continue;
      }
    } else if (job.finished + config_.retention < now) {
      expire(job);
    } else {
      kept.push_back(&job);
      total += job.result_bytes;
    }
    ++it;
  }
  std::sort(kept.begin(), kept.end(),
            [](const Job* a, const Job* b) { return a->finished < b->finished; });
  for (Job* job : kept) {
    if (total <= config_.disk_budget_bytes) break;
    total -= job->result_bytes;
    expire(*job);
  }
}

void JobStore::janitor() {
  const auto period = std::clamp<std::chrono::seconds>(
      config_.retention / 4, std::chrono::seconds(1), std::chrono::seconds(60));
  std::unique_lock lock(mutex_);
  while (!stopping_) {
    janitor_wake_.wait_for(lock, period);
    if (stopping_) break;
    lock.unlock();
    try {
      expire_now();
    } catch (const std::exception& e) {
      log_line(std::string("expiring job results failed: ") + e.what());
    }
    lock.lock();
  }
}

}  // namespace stlrefine::server
