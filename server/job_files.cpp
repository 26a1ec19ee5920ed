// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include <fcntl.h>
#include <openssl/crypto.h>
#include <sys/file.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <ctime>
#include <fstream>
#include <iostream>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "server/job_record.h"

namespace stlrefine::server::job_files {

namespace fs = std::filesystem;

namespace {

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

}  // namespace

// A job stopped by the memory budget while other work held it (admission never answers it:
// a job waits for its reservation).
api::Problem job_busy_problem(std::uint64_t needed) {
  api::Problem p = api::service_unavailable(
      "busy", "the job needed " + std::to_string((needed + (1 << 20) - 1) >> 20) +
                  " MiB while other work held the memory budget; submit it again");
  p.extensions["reason"] = "memory";
  return p;
}

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
                      mode_t mode) {
  AtomicFileOptions options;
  // Appended piece by piece: GCC 12 warns (-Wrestrict, a false positive) on "." + name here.
  options.temporary_name = ".";
  options.temporary_name += path.filename().string();
  options.temporary_name += ".tmp";
  options.mode = mode;
  try {
    write_file_atomically(path, produce, options);
  } catch (const FileError& e) {
    throw std::system_error(e.os_error(), e.what());
  }
}

void write_atomically(const fs::path& path, std::string_view bytes, mode_t mode) {
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
DirLock::DirLock(const fs::path& dir)
    : fd_(::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC)) {
  if (fd_ >= 0)
    while (::flock(fd_, LOCK_EX) != 0 && errno == EINTR) {
    }
}

DirLock::~DirLock() {
  if (fd_ >= 0) ::close(fd_);
}

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

}  // namespace stlrefine::server::job_files
