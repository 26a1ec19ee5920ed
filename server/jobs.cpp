// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/jobs.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <iostream>
#include <random>
#include <sstream>
#include <stdexcept>

#include "api/memory_model.h"
#include "api/pipeline.h"
#include "core/error.h"
#include "server/thread_priority.h"
#include "slicer/writers.h"

namespace stlrefine::server {

namespace fs = std::filesystem;
using Clock = std::chrono::system_clock;

struct JobStore::Job {
  std::string id;
  std::string owner;  // the instance running it (JobsConfig::instance)
  fs::path dir;
  api::RefineRequest request;
  std::string scheme, query;
  JobState state = JobState::Queued;
  bool expired = false;
  std::atomic<bool> cancel{false};
  double progress = 0;
  std::string stage = "queued";
  Clock::time_point created, started, finished;
  nlohmann::ordered_json report = nlohmann::ordered_json::object();
  std::optional<nlohmann::ordered_json> problem;
  std::vector<std::string> results;
  std::uint64_t result_bytes = 0;
  //! While it computes: its cancel flag (deadline, DELETE, shutdown). Under the mutex.
  std::shared_ptr<RequestWatch::Ticket> ticket;
};

namespace {

constexpr const char* kJobFile = "job.json";
constexpr const char* kInputFile = "input.stl";
constexpr const char* kCancelFile = "cancel";

const JobState kStates[] = {JobState::Queued, JobState::Running, JobState::Done, JobState::Failed,
                            JobState::Cancelled};

JobState state_from(const std::string& s) {
  for (JobState st : kStates)
    if (s == to_string(st)) return st;
  throw std::runtime_error("unknown job state '" + s + "'");
}

bool finished(JobState s) {
  return s == JobState::Done || s == JobState::Failed || s == JobState::Cancelled;
}

// Unguessable: ids are capabilities for the results behind them.
std::string new_job_id() {
  static std::mutex mutex;
  static std::mt19937_64 engine = [] {
    std::random_device rd;
    std::seed_seq seq{rd(), rd(), rd(), rd(), rd(), rd(), rd(), rd()};
    return std::mt19937_64(seq);
  }();
  std::lock_guard lock(mutex);
  char text[33];
  std::snprintf(text, sizeof text, "%016llx%016llx", static_cast<unsigned long long>(engine()),
                static_cast<unsigned long long>(engine()));
  return text;
}

// Only ids this store could have made: no path can be smuggled into the data directory.
bool well_formed_id(const std::string& id) {
  return id.size() == 32 && std::all_of(id.begin(), id.end(), [](char c) {
           return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f');
         });
}

std::int64_t epoch_ms(Clock::time_point t) {
  return std::chrono::duration_cast<std::chrono::milliseconds>(t.time_since_epoch()).count();
}

Clock::time_point from_epoch_ms(std::int64_t ms) {
  return Clock::time_point(std::chrono::milliseconds(ms));
}

std::string iso8601(Clock::time_point t) {
  const std::time_t secs = Clock::to_time_t(t);
  std::tm tm{};
  gmtime_r(&secs, &tm);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return text;
}

// Write to a temporary name in the same directory, flush to disk, rename: a reader sees
// the old file or the whole new one, never a half-written one.
void write_atomically(const fs::path& path, std::string_view bytes) {
  const fs::path tmp = path.parent_path() / ("." + path.filename().string() + ".tmp");
  {
    std::FILE* f = std::fopen(tmp.c_str(), "wb");
    if (!f) throw std::runtime_error("cannot write " + tmp.string());
    const bool ok = std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size() &&
                    std::fflush(f) == 0 && ::fsync(fileno(f)) == 0;
    std::fclose(f);
    if (!ok) {
      fs::remove(tmp);
      throw std::runtime_error("cannot write " + tmp.string());
    }
  }
  fs::rename(tmp, path);
}

std::string read_file(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path.string());
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void log_line(const std::string& line) {
  std::cerr << ("stlrefined: " + line + "\n") << std::flush;
}

}  // namespace

api::Problem deadline_problem(std::chrono::milliseconds deadline) {
  const double seconds = std::chrono::duration<double>(deadline).count();
  char text[32];
  std::snprintf(text, sizeof text, "%g", seconds);
  api::Problem p = api::make_problem(
      504, "deadline-exceeded",
      std::string("deadline exceeded: the computation ran longer than this server's request "
                  "deadline of ") +
          text + " s and was cancelled");
  p.extensions["reason"] = "deadline_exceeded";
  p.extensions["deadline_seconds"] = seconds;
  return p;
}

const char* to_string(JobState state) {
  switch (state) {
    case JobState::Queued:
      return "queued";
    case JobState::Running:
      return "running";
    case JobState::Done:
      return "done";
    case JobState::Failed:
      return "failed";
    case JobState::Cancelled:
      return "cancelled";
  }
  return "unknown";
}

nlohmann::ordered_json job_json(const JobView& job) {
  nlohmann::ordered_json j;
  const std::string self = "/v1/jobs/" + job.id;
  j["id"] = job.id;
  j["state"] = to_string(job.state);
  if (job.expired) j["expired"] = true;
  j["progress"] = job.progress;
  j["stage"] = job.stage;
  j["scheme"] = job.scheme;
  j["parameters"] = job.query;
  nlohmann::ordered_json t;
  t["created"] = iso8601(job.created);
  const bool has_started = job.started.time_since_epoch().count() != 0;
  const bool has_finished = job.finished.time_since_epoch().count() != 0;
  if (has_started) {
    t["started"] = iso8601(job.started);
    t["queued_seconds"] = std::chrono::duration<double>(job.started - job.created).count();
  }
  if (has_finished) {
    t["finished"] = iso8601(job.finished);
    if (has_started)
      t["run_seconds"] = std::chrono::duration<double>(job.finished - job.started).count();
  }
  j["timings"] = t;
  if (!job.report.empty()) j["report"] = job.report;
  if (job.problem) j["problem"] = *job.problem;
  nlohmann::ordered_json links;
  links["self"] = self;
  for (const std::string& name : job.results) {
    const std::string key = name.substr(0, name.find('.'));  // result, contours, report
    links[key] = self + "/" + name;
  }
  j["links"] = links;
  return j;
}

JobStore::JobStore(JobsConfig config, ComputeSlots& slots, FinishedFn on_finished)
    : config_(std::move(config)), slots_(slots), on_finished_(std::move(on_finished)) {
  if (config_.runners == 0) config_.runners = 1;
  if (config_.instance.empty()) {
    char host[256] = {};
    ::gethostname(host, sizeof host - 1);
    config_.instance = host;
  }
  fs::create_directories(config_.data_dir);
  load_existing();
  for (std::size_t i = 0; i < config_.runners; ++i) runners_.emplace_back([this] { run_jobs(); });
  janitor_ = std::thread([this] { janitor(); });
}

JobStore::~JobStore() {
  shutdown(std::chrono::milliseconds(0));
}

std::shared_ptr<JobStore::Job> JobStore::read_job(const fs::path& dir) const {
  const auto j = nlohmann::json::parse(read_file(dir / kJobFile));
  auto job = std::make_shared<Job>();
  job->id = dir.filename().string();
  job->dir = dir;
  job->owner = j.value("owner", "");
  job->state = state_from(j.at("state").get<std::string>());
  job->expired = j.value("expired", false);
  job->scheme = j.value("scheme", "");
  job->query = j.value("parameters", "");
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
  for (const fs::directory_entry& entry : fs::directory_iterator(config_.data_dir)) {
    const std::string id = entry.path().filename().string();
    if (!entry.is_directory() || !well_formed_id(id)) continue;
    try {
      std::shared_ptr<Job> job = read_job(entry.path());
      // Another replica's job (a shared data volume): it is read from disk when asked for.
      if (!job->owner.empty() && job->owner != config_.instance) continue;
      if (!finished(job->state)) {
        // It was queued or running when this daemon stopped: say so, never drop it silently.
        job->state = JobState::Failed;
        job->stage = "interrupted";
        job->finished = Clock::now();
        job->problem = api::to_json(api::make_problem(
            500, "interrupted", "the daemon stopped before this job finished; submit it again"));
        fs::remove(job->dir / kInputFile);
        persist(*job);
      }
      jobs_.emplace(id, std::move(job));
    } catch (const std::exception& e) {
      log_line("skipping job directory " + entry.path().string() + ": " + e.what());
    }
  }
}

void JobStore::persist(const Job& job) const {
  nlohmann::ordered_json j;
  j["id"] = job.id;
  j["owner"] = job.owner;
  j["state"] = to_string(job.state);
  j["expired"] = job.expired;
  j["scheme"] = job.scheme;
  j["parameters"] = job.query;
  j["progress"] = job.progress;
  j["stage"] = job.stage;
  j["created_ms"] = epoch_ms(job.created);
  j["started_ms"] = epoch_ms(job.started);
  j["finished_ms"] = epoch_ms(job.finished);
  if (!job.report.empty()) j["report"] = job.report;
  if (job.problem) j["problem"] = *job.problem;
  j["results"] = job.results;
  j["result_bytes"] = job.result_bytes;
  write_atomically(job.dir / kJobFile, j.dump(2) + "\n");
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

JobView JobStore::view(const Job& job) const {
  JobView v;
  v.id = job.id;
  v.state = job.state;
  v.expired = job.expired;
  v.progress = job.progress;
  v.stage = job.stage;
  v.scheme = job.scheme;
  v.query = job.query;
  v.created = job.created;
  v.started = job.started;
  v.finished = job.finished;
  v.report = job.report;
  v.problem = job.problem;
  if (!job.expired) v.results = job.results;
  return v;
}

std::optional<JobView> JobStore::submit(api::RefineRequest request, std::string query,
                                        std::string_view stl_bytes) {
  auto job = std::make_shared<Job>();
  job->id = new_job_id();
  job->owner = config_.instance;
  job->dir = config_.data_dir / job->id;
  job->scheme = request.refine.scheme;
  job->query = std::move(query);
  job->request = std::move(request);
  job->created = Clock::now();
  {
    std::lock_guard lock(mutex_);
    if (stopping_ || queue_.size() >= config_.max_queued) return std::nullopt;
  }
  // The input goes to disk before the job is visible, so a queued job holds no memory.
  fs::create_directories(job->dir);
  write_atomically(job->dir / kInputFile, stl_bytes);
  persist(*job);
  std::lock_guard lock(mutex_);
  if (stopping_ || queue_.size() >= config_.max_queued) {
    fs::remove_all(job->dir);
    return std::nullopt;
  }
  jobs_.emplace(job->id, job);
  queue_.push_back(job);
  work_.notify_one();
  return view(*job);
}

JobStore::Lookup JobStore::find_on_disk(const std::string& id, JobView* out) const {
  if (!well_formed_id(id)) return Lookup::Unknown;
  std::error_code ec;
  if (!fs::exists(config_.data_dir / id / kJobFile, ec)) return Lookup::Unknown;
  try {
    const std::shared_ptr<Job> job = read_job(config_.data_dir / id);
    if (out) *out = view(*job);
    return job->expired ? Lookup::Expired : Lookup::Found;
  } catch (const std::exception&) {
    return Lookup::Unknown;  // being written by its owner for the first time
  }
}

JobStore::Lookup JobStore::find(const std::string& id, JobView* out) const {
  std::lock_guard lock(mutex_);
  const auto it = well_formed_id(id) ? jobs_.find(id) : jobs_.end();
  if (it == jobs_.end()) return find_on_disk(id, out);
  if (out) *out = view(*it->second);
  return it->second->expired ? Lookup::Expired : Lookup::Found;
}

JobStore::Lookup JobStore::cancel(const std::string& id, JobView* out) {
  std::lock_guard lock(mutex_);
  const auto it = well_formed_id(id) ? jobs_.find(id) : jobs_.end();
  if (it == jobs_.end()) {
    // Another replica's job: leave a note its runner picks up at the next progress step.
    const Lookup found = find_on_disk(id, out);
    if (found == Lookup::Found && out && !finished(out->state)) {
      std::ofstream(config_.data_dir / id / kCancelFile) << "cancel\n";
      out->stage = "cancel requested";
    }
    return found;
  }
  Job& job = *it->second;
  if (job.expired) {
    if (out) *out = view(job);
    return Lookup::Expired;
  }
  job.cancel = true;
  if (job.ticket) job.ticket->raise(RequestWatch::Reason::Cancelled);
  if (job.state == JobState::Queued) {
    queue_.erase(std::remove(queue_.begin(), queue_.end(), it->second), queue_.end());
    job.state = JobState::Cancelled;
    job.stage = "cancelled";
    job.finished = Clock::now();
    job.problem = api::to_json(api::make_problem(409, "cancelled", "cancelled by the client"));
    fs::remove(job.dir / kInputFile);
    persist(job);
  } else if (finished(job.state)) {
    expire(job);  // DELETE of a finished job frees its disk space
  }
  if (out) *out = view(job);
  return job.expired ? Lookup::Expired : Lookup::Found;
}

fs::path JobStore::result_path(const std::string& id, const std::string& name) const {
  return config_.data_dir / id / name;
}

std::size_t JobStore::queued() const {
  std::lock_guard lock(mutex_);
  return queue_.size();
}

std::size_t JobStore::running() const {
  std::lock_guard lock(mutex_);
  return running_;
}

void JobStore::run_jobs() {
  lower_thread_priority(config_.runner_nice);
  for (;;) {
    std::shared_ptr<Job> job;
    {
      std::unique_lock lock(mutex_);
      work_.wait(lock, [&] { return !queue_.empty() || stopping_; });
      if (stopping_) return;
      job = queue_.front();
      queue_.pop_front();
      ++running_;
      job->state = JobState::Running;
      job->stage = "waiting for a compute slot";
    }
    run_one(job);
    std::lock_guard lock(mutex_);
    --running_;
    work_.notify_all();  // shutdown() waits for running_ == 0
  }
}

void JobStore::run_one(const std::shared_ptr<Job>& job) {
  // Jobs share the compute slots with the synchronous routes: wait for one, polling so a
  // cancel or shutdown is seen.
  std::optional<ComputeSlots::Lease> lease;
  while (!(lease = slots_.try_acquire()) && !job->cancel && !cancel_all_)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  {
    std::lock_guard lock(mutex_);
    job->started = Clock::now();
    job->stage = "starting";
    persist_or_log(*job);
  }
  JobState state = JobState::Failed;
  std::optional<api::Problem> problem;
  nlohmann::ordered_json report;
  std::vector<std::string> results;
  std::uint64_t bytes = 0;
  std::optional<MemoryBudget::Reservation> memory;
  std::shared_ptr<RequestWatch::Ticket> ticket;
  const auto cancelled = [&] { return job->cancel || cancel_all_; };
  struct Refused {
    api::Problem problem;
  };
  try {
    if (!lease) throw Error(ErrorCode::Cancelled, "cancelled", "cancelled before it started");
    const std::string input = read_file(job->dir / kInputFile);
    const auto input_bytes =
        std::span(reinterpret_cast<const std::uint8_t*>(input.data()), input.size());
    if (config_.memory) {
      // Its predicted peak, before any work (the face budget first, as in run_refine); it
      // waits for that like for a slot.
      const api::StlShape shape = api::stl_shape(input_bytes);
      api::refuse_over_face_budget(shape.faces, job->request.refine);
      const api::MemoryEstimate predicted =
          api::estimate_refine_memory(input_bytes, shape, job->request, api::ResultSink::JobFiles);
      if (predicted.peak_bytes > config_.memory->capacity())
        throw Refused{api::memory_budget_problem(predicted, config_.memory->capacity())};
      if (!(memory = config_.memory->try_reserve(predicted.peak_bytes))) {
        {
          std::lock_guard lock(mutex_);
          job->stage = "waiting for memory";
        }
        while (!(memory = config_.memory->try_reserve(predicted.peak_bytes)) && !cancelled())
          std::this_thread::sleep_for(std::chrono::milliseconds(20));
        if (!memory) throw Error(ErrorCode::Cancelled, "cancelled", "cancelled before it started");
      }
    }
    {
      // The deadline counts from here; DELETE and shutdown raise the same flag.
      std::lock_guard lock(mutex_);
      ticket = watch_.watch(-1, config_.deadline);
      job->ticket = ticket;
      if (job->cancel) ticket->raise(RequestWatch::Reason::Cancelled);
    }
    auto progress = [&](double fraction, std::string_view stage) {
      std::error_code ec;
      if (fs::exists(job->dir / kCancelFile, ec)) {  // from another replica
        job->cancel = true;
        ticket->raise(RequestWatch::Reason::Cancelled);
      }
      std::lock_guard lock(mutex_);
      job->progress = std::clamp(fraction, 0.0, 1.0);
      job->stage = std::string(stage);
    };
    api::RefineOutcome out = api::run_refine(input_bytes, job->request, progress, &ticket->cancel);
    report = out.report;
    write_atomically(job->dir / "result.stl", out.stl);
    results.push_back("result.stl");
    bytes += out.stl.size();
    if (out.contours) {
      const std::string name =
          std::string("contours") + slicer::file_extension(job->request.slice->format);
      write_atomically(job->dir / name, *out.contours);
      results.push_back(name);
      bytes += out.contours->size();
    }
    const std::string report_text = report.dump(2) + "\n";
    write_atomically(job->dir / "report.json", report_text);
    results.push_back("report.json");
    bytes += report_text.size();
    state = JobState::Done;
  } catch (const Refused& r) {
    problem = r.problem;
  } catch (const Error& e) {
    if (e.code() == ErrorCode::Cancelled && ticket &&
        ticket->reason() == RequestWatch::Reason::Deadline) {
      problem = deadline_problem(config_.deadline);
    } else if (e.code() == ErrorCode::Cancelled || job->cancel || cancel_all_) {
      state = JobState::Cancelled;
      problem = api::make_problem(409, "cancelled",
                                  cancel_all_ && !job->cancel ? "cancelled: the server shut down"
                                                              : "cancelled by the client");
    } else {
      problem = api::problem_from_error(e);
    }
  } catch (const std::exception& e) {
    log_line("job " + job->id + " failed: " + e.what());
    problem = api::make_problem(500, "internal", "an internal error occurred");
  }
  lease.reset();
  memory.reset();
  fs::remove(job->dir / kInputFile);

  JobView done;
  {
    std::lock_guard lock(mutex_);
    job->ticket.reset();
    job->state = state;
    job->finished = Clock::now();
    job->progress = state == JobState::Done ? 1.0 : job->progress;
    job->stage = to_string(state);
    job->report = std::move(report);
    if (problem) job->problem = api::to_json(*problem);
    job->results = std::move(results);
    job->result_bytes = bytes;
    persist_or_log(*job);
    done = view(*job);
  }
  if (on_finished_)
    on_finished_(done, std::chrono::duration<double>(done.finished - done.started).count());
  janitor_wake_.notify_one();  // the disk budget may now be exceeded
}

void JobStore::expire(Job& job) {
  for (const std::string& name : job.results) fs::remove(job.dir / name);
  job.expired = true;
  job.result_bytes = 0;
  persist(job);
}

void JobStore::expire_now() {
  std::lock_guard lock(mutex_);
  const auto now = Clock::now();
  std::vector<Job*> kept;
  std::uint64_t total = 0;
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

void JobStore::cancel_running() {
  std::lock_guard lock(mutex_);
  cancel_all_ = true;
  for (auto& [id, job] : jobs_) {
    if (job->state != JobState::Running) continue;
    job->cancel = true;
    if (job->ticket) job->ticket->raise(RequestWatch::Reason::Shutdown);
  }
}

void JobStore::shutdown(std::chrono::milliseconds grace) {
  {
    std::unique_lock lock(mutex_);
    if (!stopping_) {
      stopping_ = true;
      for (const auto& job : queue_) {
        job->state = JobState::Failed;
        job->stage = "shutting down";
        job->finished = Clock::now();
        job->problem = api::to_json(api::make_problem(
            503, "shutting-down", "the server shut down before this job started; submit it again"));
        fs::remove(job->dir / kInputFile);
        persist(*job);
      }
      queue_.clear();
    }
    work_.notify_all();
    janitor_wake_.notify_all();
    // Running jobs may finish within the grace period; then they are cancelled.
    if (!work_.wait_for(lock, grace, [&] { return running_ == 0; })) {
      lock.unlock();
      cancel_running();
    }
  }
  for (std::thread& t : runners_)
    if (t.joinable()) t.join();
  if (janitor_.joinable()) janitor_.join();
}

}  // namespace stlrefine::server
