// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/jobs.h"

#include <fcntl.h>
#include <malloc.h>
#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/hmac.h>
#include <sys/file.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <functional>
#include <iostream>
#include <limits>
#include <set>
#include <sstream>
#include <stdexcept>
#include <system_error>

#include "api/memory_model.h"
#include "api/pipeline.h"
#include "api/plan.h"
#include "core/error.h"
#include "core/io/atomic_file.h"
#include "core/io/stl.h"
#include "server/admission.h"
#include "server/thread_priority.h"
#include "slicer/writers.h"

namespace stlrefine::server {

namespace fs = std::filesystem;
using Clock = std::chrono::system_clock;

struct JobStore::Job {
  std::string id;
  std::string instance;  // the replica running it (JobsConfig::instance); "owner" on disk
  std::string tenant;    // who may see it (submit's owner); "tenant" on disk
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
  //! Its share of committed_disk_ (its predicted results) until it finishes.
  std::uint64_t reserved_disk = 0;
  //! Who cancelled it first (under the mutex; `cancel` is raised with it).
  CancelReason cancel_reason = CancelReason::None;
  //! While it computes: its cancel flag (deadline, DELETE, shutdown). Under the mutex.
  std::shared_ptr<RequestWatch::Ticket> ticket;
};

struct JobStore::Leftovers {
  std::uint64_t tmp_bytes = 0;         // *.tmp files of this store's jobs still there
  std::vector<std::string> to_delete;  // this store's jobs another replica deleted
};

namespace {

// A job stopped by the memory budget while other work held it (admission never answers it:
// a job waits for its reservation).
api::Problem job_busy_problem(std::uint64_t needed) {
  api::Problem p = api::service_unavailable(
      "busy", "the job needed " + std::to_string((needed + (1 << 20) - 1) >> 20) +
                  " MiB while other work held the memory budget; submit it again");
  p.extensions["reason"] = "memory";
  return p;
}

constexpr const char* kJobFile = "job.json";
constexpr const char* kInputFile = "input.stl";
// How long a running job waits for memory its refinement needs next (held by other work).
constexpr std::chrono::seconds kGrowWait{10};
// Notes from another replica sharing the data directory, for the job's owner: cancel it
// (running), delete its results (finished).
constexpr const char* kCancelFile = "cancel";
constexpr const char* kDeleteFile = "delete";
constexpr const char* kTenantKeyFile = ".tenant-key";
constexpr std::size_t kTenantKeyBytes = 32;
// A job directory without job.json, or a *.tmp file, untouched this long is what a crash
// (or SIGKILL) left in the middle of a write.
constexpr auto kLeftoverAge = std::chrono::seconds(60);

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

[[noreturn]] void throw_errno(int err, const std::string& what) {
  throw std::system_error(err, std::generic_category(), what);
}

// Bytes from the kernel's CSPRNG (getrandom(2), blocking until it is seeded). There is no
// fallback: without it the store cannot make ids or its tenant key, and says so.
void random_bytes(unsigned char* out, std::size_t size) {
  while (size > 0) {
    const ssize_t got = ::getrandom(out, size, 0);
    if (got < 0) {
      if (errno == EINTR) continue;
      throw_errno(errno, "getrandom");
    }
    out += got;
    size -= static_cast<std::size_t>(got);
  }
}

std::string hex(const unsigned char* bytes, std::size_t size) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string text(2 * size, '0');
  for (std::size_t i = 0; i < size; ++i) {
    text[2 * i] = kDigits[bytes[i] >> 4];
    text[2 * i + 1] = kDigits[bytes[i] & 15];
  }
  return text;
}

// Unguessable: ids are capabilities for the results behind them. 128 bits from the OS, as
// 32 lowercase hex digits (URL-safe, and the form earlier versions wrote).
std::string new_job_id() {
  unsigned char bits[16];
  random_bytes(bits, sizeof bits);
  return hex(bits, sizeof bits);
}

// Only ids this store could have made: no path can be smuggled into the data directory.
bool well_formed_id(const std::string& id) {
  return id.size() == 32 && std::all_of(id.begin(), id.end(), [](char c) {
           return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f');
         });
}

// Owners are compared without an early exit: another tenant's job answers like an unknown
// one, in the same time.
bool same_tenant(const std::string& a, const std::string& b) {
  return a.size() == b.size() && CRYPTO_memcmp(a.data(), b.data(), a.size()) == 0;
}

// A write that failed for want of space (the device, a quota, a file size limit): the
// client may retry later; it is not the server's fault.
bool no_space(const std::error_code& ec) {
  const std::error_condition c = ec.default_error_condition();
  return c == std::errc::no_space_on_device || c == std::errc::file_too_large ||
         c == std::error_condition(EDQUOT, std::generic_category());
}

api::Problem no_space_result_problem() {
  api::Problem p = api::insufficient_storage(
      "insufficient-storage",
      "no space left on the device: the results could not be written; submit the job again "
      "later");
  p.extensions["reason"] = "no_space";
  return p;
}

std::uint64_t saturating_add(std::uint64_t a, std::uint64_t b) {
  return a > std::numeric_limits<std::uint64_t>::max() - b
             ? std::numeric_limits<std::uint64_t>::max()
             : a + b;
}

std::uint64_t statvfs_free(const fs::path& dir) {
  struct statvfs s {};
  if (::statvfs(dir.c_str(), &s) != 0) return std::numeric_limits<std::uint64_t>::max();
  return static_cast<std::uint64_t>(s.f_bavail) * static_cast<std::uint64_t>(s.f_frsize);
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

// The core's atomic writer (core/io/atomic_file.h) with the temporary name ".<name>.tmp",
// which the janitor knows as a crash's leftover: a reader sees the old file or the whole
// new one, never a half-written one, and a failure (ENOSPC, ...) leaves neither the
// temporary file nor a changed `path`. Its failures come out as std::system_error carrying
// the system's code, which the runner turns into 507 when it is a full disk.
void write_atomically(const fs::path& path, const std::function<void(const ByteSink&)>& produce,
                      mode_t mode = 0644) {
  AtomicFileOptions options;
  options.temporary_name = "." + path.filename().string() + ".tmp";
  options.mode = mode;
  try {
    write_file_atomically(path, produce, options);
  } catch (const FileError& e) {
    throw std::system_error(e.os_error(), e.what());
  }
}

void write_atomically(const fs::path& path, std::string_view bytes, mode_t mode = 0644) {
  write_atomically(
      path, [bytes](const ByteSink& sink) { sink(bytes); }, mode);
}

bool is_tmp(const fs::path& path) {
  const std::string name = path.filename().string();
  return name.size() > 4 && name.compare(name.size() - 4, 4, ".tmp") == 0;
}

// A crash's leftover: untouched (the entry and, for a directory, its entries) for
// kLeftoverAge. Anything younger may be another replica's write in progress.
bool left_over(const fs::path& path, fs::file_time_type now) {
  std::error_code ec;
  fs::file_time_type newest = fs::last_write_time(path, ec);
  if (ec) return false;
  if (fs::is_directory(path, ec))
    for (const fs::directory_entry& e : fs::directory_iterator(path, ec)) {
      const fs::file_time_type t = e.last_write_time(ec);
      if (!ec) newest = std::max(newest, t);
    }
  return newest + kLeftoverAge < now;
}

// An exclusive flock(2) on a job's directory, held while the owner writes a job's final
// state and while another replica reads it to leave a cancel note: the note arrives before
// the final state (and the job is cancelled) or the replica sees the job finished. Best
// effort: where directories cannot be locked, nothing is.
class DirLock {
 public:
  explicit DirLock(const fs::path& dir)
      : fd_(::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC)) {
    if (fd_ >= 0)
      while (::flock(fd_, LOCK_EX) != 0 && errno == EINTR) {
      }
  }
  ~DirLock() {
    if (fd_ >= 0) ::close(fd_);
  }
  DirLock(const DirLock&) = delete;
  DirLock& operator=(const DirLock&) = delete;

 private:
  int fd_;
};

// The data directory's tenant secret: read it, or make it (first start). Made under a
// unique temporary name and link(2)ed into place, so two replicas starting together on an
// empty directory end with the same secret, and a crash never leaves a short one.
std::array<unsigned char, kTenantKeyBytes> load_tenant_key(const fs::path& data_dir) {
  const fs::path path = data_dir / kTenantKeyFile;
  std::array<unsigned char, kTenantKeyBytes> key{};
  for (int attempt = 0; attempt < 3; ++attempt) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NOFOLLOW);
    if (fd >= 0) {
      std::size_t got = 0;
      unsigned char extra = 0;
      ssize_t n = 0;
      while (got < key.size() && ((n = ::read(fd, key.data() + got, key.size() - got)) > 0 ||
                                  (n < 0 && errno == EINTR)))
        if (n > 0) got += static_cast<std::size_t>(n);
      while ((n = ::read(fd, &extra, 1)) < 0 && errno == EINTR) {
      }
      struct stat st {};
      const bool lax = ::fstat(fd, &st) == 0 && (st.st_mode & 077) != 0;
      ::close(fd);
      if (got != key.size() || n != 0)
        throw std::runtime_error(path.string() + " is not the " + std::to_string(kTenantKeyBytes) +
                                 "-byte tenant secret this daemon writes; remove it to make a "
                                 "new one (jobs submitted with an API key then become "
                                 "unreachable)");
      if (lax) std::cerr << "stlrefined: " + path.string() + " is readable by others (chmod 600)\n";
      return key;
    }
    if (errno != ENOENT) throw_errno(errno, "cannot read " + path.string());
    random_bytes(key.data(), key.size());
    unsigned char name[8];
    random_bytes(name, sizeof name);
    const fs::path tmp =
        data_dir / (std::string(kTenantKeyFile) + "." + hex(name, sizeof name) + ".tmp");
    write_atomically(tmp, std::string_view(reinterpret_cast<const char*>(key.data()), key.size()),
                     0600);
    int rc = ::link(tmp.c_str(), path.c_str());
    int err = rc == 0 ? 0 : errno;
    if (rc != 0 && (err == EPERM || err == EOPNOTSUPP || err == ENOSYS)) {
      // A file system without hard links: rename (a replica starting in the same instant
      // may then replace it once, before any job was submitted with it).
      rc = ::rename(tmp.c_str(), path.c_str());
      err = rc == 0 ? 0 : errno;
    }
    ::unlink(tmp.c_str());
    OPENSSL_cleanse(key.data(), key.size());
    if (rc != 0 && err != EEXIST) throw_errno(err, "cannot create " + path.string());
    // Read back what is there now: ours, or the secret of a replica that was first.
  }
  throw std::runtime_error("cannot create " + path.string());
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
  api::Problem p = api::gateway_timeout(
      "deadline-exceeded",
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

api::Problem no_space_problem(const SubmitResult& refused) {
  api::Problem p = api::insufficient_storage(
      "insufficient-storage",
      "not enough free space for this job's input and results on the server's data "
      "directory; retry later");
  p.extensions["reason"] = "no_space";
  p.extensions["needed_bytes"] = refused.needed_bytes;
  p.extensions["free_bytes"] = refused.free_bytes;
  return p;
}

std::uint64_t predicted_result_bytes(const api::RefineRequest& request,
                                     const api::MemoryEstimate& predicted) {
  // A binary facet is 50 bytes; an ASCII one ("facet normal ... endfacet" with %e numbers)
  // under 300. Contour points: at most 48 bytes in the text formats. The report: 64 KiB.
  const std::uint64_t facet = request.output_format == StlFormat::Binary ? 50 : 300;
  std::uint64_t bytes = saturating_add(
      84, facet > 0 && predicted.output_faces > std::numeric_limits<std::uint64_t>::max() / facet
              ? std::numeric_limits<std::uint64_t>::max()
              : facet * predicted.output_faces);
  if (request.slice)
    bytes = saturating_add(bytes,
                           predicted.contour_points > std::numeric_limits<std::uint64_t>::max() / 48
                               ? std::numeric_limits<std::uint64_t>::max()
                               : 48 * predicted.contour_points);
  return saturating_add(bytes, std::uint64_t{64} << 10);
}

JobStore::JobStore(JobsConfig config, ComputeSlots& slots, FinishedFn on_finished)
    : config_(std::move(config)), slots_(slots), on_finished_(std::move(on_finished)) {
  if (config_.runners == 0) config_.runners = 1;
  if (config_.instance.empty()) {
    char host[256] = {};
    ::gethostname(host, sizeof host - 1);
    config_.instance = host;
  }
  if (!config_.free_bytes)
    config_.free_bytes = [dir = config_.data_dir] { return statvfs_free(dir); };
  fs::create_directories(config_.data_dir);
  tenant_key_ = load_tenant_key(config_.data_dir);
  load_existing();
  for (std::size_t i = 0; i < config_.runners; ++i) runners_.emplace_back([this] { run_jobs(); });
  janitor_ = std::thread([this] { janitor(); });
}

JobStore::~JobStore() {
  shutdown(std::chrono::milliseconds(0));
  OPENSSL_cleanse(tenant_key_.data(), tenant_key_.size());
}

std::string JobStore::tenant_of(std::string_view api_key) const {
  unsigned char mac[EVP_MAX_MD_SIZE];
  unsigned int size = 0;
  if (!HMAC(EVP_sha256(), tenant_key_.data(), static_cast<int>(tenant_key_.size()),
            reinterpret_cast<const unsigned char*>(api_key.empty() ? "" : api_key.data()),
            api_key.size(), mac, &size) ||
      size < 16)
    throw std::runtime_error("HMAC-SHA256 failed");
  return hex(mac, 16);
}

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
        job->finished = Clock::now();
        if (fs::exists(job->dir / kCancelFile, ec)) {
          job->state = JobState::Cancelled;
          job->stage = "cancelled";
          job->problem = api::to_json(cancel_problem(CancelReason::Client, false));
        } else {
          job->state = JobState::Failed;
          job->stage = "interrupted";
          job->problem = api::to_json(api::server_error(
              "interrupted", "the daemon stopped before this job finished; submit it again"));
        }
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
  nlohmann::ordered_json j;
  j["id"] = job.id;
  j["owner"] = job.instance;
  j["tenant"] = job.tenant;
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

void JobStore::release_disk(Job& job) {
  committed_disk_ -= std::min(committed_disk_, job.reserved_disk);
  job.reserved_disk = 0;
}

SubmitResult JobStore::submit(api::RefineRequest request, std::string query,
                              std::string_view stl_bytes, std::string owner,
                              std::uint64_t predicted_result_bytes) {
  using Status = SubmitResult::Status;
  std::uint64_t needed = 0;
  auto job = std::make_shared<Job>();
  job->id = new_job_id();
  job->instance = config_.instance;
  job->tenant = std::move(owner);
  job->dir = config_.data_dir / job->id;
  job->scheme = request.refine.scheme;
  job->query = std::move(query);
  job->request = std::move(request);
  job->created = Clock::now();
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

JobStore::Lookup JobStore::cancel(const std::string& id, const std::string& owner, JobView* out) {
  if (!well_formed_id(id)) return Lookup::Unknown;
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
  const auto cancelled = [&] { return job->cancel || cancel_all_ || cancel_noted(*job); };
  // Jobs share the compute slots with the synchronous routes: wait for one, polling so a
  // cancel or shutdown is seen.
  std::optional<ComputeSlots::Lease> lease;
  while (!(lease = slots_.try_acquire()) && !cancelled())
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  {
    std::lock_guard lock(mutex_);
    job->started = Clock::now();
    job->stage = "starting";
    persist_or_log(*job);
  }
  // Done: results written; Cancelled: stopped by a cancel (which one is decided below,
  // under the lock); Failed: `problem`.
  JobState state = JobState::Failed;
  std::optional<api::Problem> problem;
  nlohmann::ordered_json report;
  std::vector<std::string> results;
  std::uint64_t bytes = 0;
  std::optional<MemoryBudget::Reservation> memory;
  std::shared_ptr<RequestWatch::Ticket> ticket;
  struct Refused {
    api::Problem problem;
  };
  try {
    if (!lease) throw Error(ErrorCode::Cancelled, "cancelled", "cancelled before it started");
    const std::string input = read_file(job->dir / kInputFile);
    const auto input_bytes =
        std::span(reinterpret_cast<const std::uint8_t*>(input.data()), input.size());
    // The request was parsed and validated when it was submitted; planned on its body now.
    const api::RefinePlan plan =
        api::plan_refine(job->request, input_bytes, api::ResultSink::JobFiles);
    if (config_.memory) {
      // Its predicted peak, before any work (the face budget first); it waits for that like
      // for a slot.
      const ReserveFn reserve = [&](std::uint64_t peak) {
        if ((memory = config_.memory->try_reserve(peak))) return true;
        {
          std::lock_guard lock(mutex_);
          job->stage = "waiting for memory";
        }
        while (!(memory = config_.memory->try_reserve(peak)) && !cancelled())
          std::this_thread::sleep_for(std::chrono::milliseconds(20));
        if (!memory) throw Error(ErrorCode::Cancelled, "cancelled", "cancelled before it started");
        return true;
      };
      if (std::optional<api::Problem> refused =
              admit(plan, config_.memory->capacity(), reserve, job_busy_problem))
        throw Refused{*refused};
    }
    {
      // The deadline counts from here; DELETE and shutdown raise the same flag.
      std::lock_guard lock(mutex_);
      ticket = watch_.watch(-1, config_.deadline);
      job->ticket = ticket;
      if (job->cancel)
        ticket->raise(job->cancel_reason == CancelReason::Client ? RequestWatch::Reason::Cancelled
                                                                 : RequestWatch::Reason::Shutdown);
    }
    auto progress = [&](double fraction, std::string_view stage) {
      cancel_noted(*job);  // from another replica
      std::lock_guard lock(mutex_);
      job->progress = std::clamp(fraction, 0.0, 1.0);
      job->stage = std::string(stage);
    };
    // The reservation grows with the refinement. Memory held by other work may come back:
    // wait for it a while (cancellable), then give up rather than hold half a hierarchy.
    auto grow = [&](std::uint64_t needed) {
      if (!memory) return true;  // no budget configured
      if (needed > config_.memory->capacity()) return false;
      const auto until = std::chrono::steady_clock::now() + kGrowWait;
      while (!memory->grow_to(needed)) {
        if (std::chrono::steady_clock::now() > until || ticket->cancel) return false;
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
      }
      return true;
    };
    api::RefinedMesh refined =
        api::run_refine_to_mesh(input_bytes, plan, progress, &ticket->cancel, grow);
    const api::RefineOutcome& out = refined.outcome;
    report = out.report;
    // Each file is listed once it is whole, so a failure below removes exactly those.
    if (refined.stream()) {  // binary: made as it is written, never whole in memory
      const auto start = std::chrono::steady_clock::now();
      write_atomically(job->dir / "result.stl",
                       [&](const ByteSink& sink) { write_binary_stl(refined.mesh, sink); });
      bytes += binary_stl_size(refined.mesh.num_faces());
      // The report's write time is the streamed write's (run_refine's included its own).
      const double seconds =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      report["seconds"]["write"] = seconds;
      report["seconds"]["total"] = report["seconds"]["total"].get<double>() + seconds;
    } else {
      write_atomically(job->dir / "result.stl", out.stl);
      bytes += out.stl.size();
    }
    results.push_back("result.stl");
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
  } catch (const MemoryBudgetError& e) {
    if (job->cancel || cancel_all_) {
      state = JobState::Cancelled;
    } else {
      problem = config_.memory ? memory_problem(e, config_.memory->capacity(), job_busy_problem)
                               : api::problem_from_error(e);
    }
  } catch (const Error& e) {
    if (e.code() == ErrorCode::Cancelled || job->cancel || cancel_all_)
      state = JobState::Cancelled;
    else
      problem = api::problem_from_error(e);
  } catch (const std::system_error& e) {
    if (no_space(e.code())) {
      log_line("job " + job->id + " failed: " + e.what());
      problem = no_space_result_problem();
    } else {
      log_line("job " + job->id + " failed: " + e.what());
      problem = api::internal_error();
    }
  } catch (const std::exception& e) {
    log_line("job " + job->id + " failed: " + e.what());
    problem = api::internal_error();
  }
  lease.reset();
  ::malloc_trim(0);  // what the refinement freed goes back before its reservation does
  memory.reset();
  std::error_code ignored;
  fs::remove(job->dir / kInputFile, ignored);
  const auto discard = [&] {
    for (const std::string& name : results) fs::remove(job->dir / name, ignored);
    results.clear();
    bytes = 0;
  };
  if (state != JobState::Done) discard();  // a write that failed half-way

  JobView done;
  {
    // Another replica's cancel note is either here now, or it finds the job finished.
    DirLock dir_lock(job->dir);
    std::lock_guard lock(mutex_);
    if (fs::exists(job->dir / kCancelFile, ignored)) request_cancel(*job, CancelReason::Client);
    const CancelReason why = job->cancel_reason;
    if (why == CancelReason::Client) {
      // A cancel answered Found before this point: it wins, even over finished work.
      const bool discarded = state == JobState::Done;
      discard();
      state = JobState::Cancelled;
      problem = cancel_problem(why, discarded);
    } else if (state == JobState::Cancelled) {
      if (ticket && ticket->reason() == RequestWatch::Reason::Deadline) {
        state = JobState::Failed;
        problem = deadline_problem(config_.deadline);
      } else {
        problem = cancel_problem(why != CancelReason::None ? why : shutdown_reason_, false);
      }
    }
    job->ticket.reset();
    job->state = state;
    job->finished = Clock::now();
    job->progress = state == JobState::Done ? 1.0 : job->progress;
    job->stage = to_string(state);
    job->report = std::move(report);
    if (problem) job->problem = api::to_json(*problem);
    job->results = results;
    job->result_bytes = bytes;
    release_disk(*job);
    std::optional<std::error_code> unrecorded;
    try {
      persist(*job);
    } catch (const std::exception& e) {
      log_line("job " + job->id + ": cannot record its state: " + e.what());
      const auto* error = dynamic_cast<const std::system_error*>(&e);
      unrecorded = error ? error->code() : std::error_code();
    }
    if (unrecorded && state == JobState::Done) {
      // Results nobody can find after a restart, and that replicas see running forever:
      // rather a failed job (job.json's last write was "starting").
      discard();
      job->state = JobState::Failed;
      job->stage = to_string(JobState::Failed);
      job->problem =
          api::to_json(no_space(*unrecorded) ? no_space_result_problem() : api::internal_error());
      job->results.clear();
      job->result_bytes = 0;
      persist_or_log(*job);
    }
    done = view(*job);
  }
  if (on_finished_)
    on_finished_(done, std::chrono::duration<double>(done.finished - done.started).count());
  janitor_wake_.notify_one();  // the disk budget may now be exceeded
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
        job->finished = Clock::now();
        if (fs::exists(job->dir / kCancelFile, ignored)) {  // accepted by another replica
          job->state = JobState::Cancelled;
          job->stage = "cancelled";
          job->problem = api::to_json(cancel_problem(CancelReason::Client, false));
        } else {
          job->state = JobState::Failed;
          job->stage = "shutting down";
          job->problem = api::to_json(api::service_unavailable(
              "shutting-down", "the server shut down before this job started; submit it again"));
        }
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
}

}  // namespace stlrefine::server
