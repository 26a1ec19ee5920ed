// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/io/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdint>
#include <utility>

namespace stlrefine {
namespace {

// Pieces are gathered up to this much before a write(2).
constexpr std::size_t kGather = std::size_t{1} << 20;

FileError file_error(ErrorCode code, const char* reason, const std::string& what,
                     const std::filesystem::path& path, int err) {
  const std::error_code os(err, std::generic_category());
  return FileError(code, reason, what + " '" + path.string() + "': " + os.message(), os);
}

//! The open temporary file: written in full or removed.
class TempFile {
 public:
  TempFile(std::filesystem::path path, int flags, mode_t mode) : path_(std::move(path)) {
    fd_ = ::open(path_.c_str(), flags, mode);
    if (fd_ < 0)
      throw file_error(ErrorCode::InvalidParameter, "cannot_create", "cannot create", path_, errno);
  }
  ~TempFile() {
    if (fd_ >= 0) ::close(fd_);
    if (!kept_) ::unlink(path_.c_str());
  }
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;

  void write(std::string_view bytes) {
    while (!bytes.empty()) {
      const ssize_t n = ::write(fd_, bytes.data(), bytes.size());
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0)
        throw file_error(ErrorCode::Internal, "write_failed", "cannot write", path_,
                         n < 0 ? errno : EIO);
      bytes.remove_prefix(static_cast<std::size_t>(n));
    }
  }

  //! fsync, close, rename over `target`: from here on the temporary name is gone.
  void commit(const std::filesystem::path& target) {
    if (::fsync(fd_) != 0)
      throw file_error(ErrorCode::Internal, "write_failed", "cannot sync", path_, errno);
    const int fd = std::exchange(fd_, -1);
    if (::close(fd) != 0 && errno != EINTR)
      throw file_error(ErrorCode::Internal, "write_failed", "cannot close", path_, errno);
    if (::rename(path_.c_str(), target.c_str()) != 0)
      throw file_error(ErrorCode::InvalidParameter, "cannot_create", "cannot replace", target,
                       errno);
    kept_ = true;
  }

 private:
  std::filesystem::path path_;
  int fd_ = -1;
  bool kept_ = false;
};

// The rename is durable once the directory's entry is: fsync the directory. File systems
// that cannot sync a directory say EINVAL (nothing to do there); one that cannot be opened
// for reading (write and search permission only) cannot be synced by us either.
void sync_directory(const std::filesystem::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return;
  const int rc = ::fsync(fd);
  const int err = errno;
  ::close(fd);
  if (rc != 0 && err != EINVAL && err != EROFS)
    throw file_error(ErrorCode::Internal, "write_failed", "cannot sync the directory", dir, err);
}

}  // namespace

void write_file_atomically(const std::filesystem::path& path,
                           const std::function<void(const ByteSink& sink)>& produce,
                           const AtomicFileOptions& options) {
  const std::filesystem::path dir =
      path.has_parent_path() ? path.parent_path() : std::filesystem::path(".");
  std::filesystem::path tmp;
  int flags = O_WRONLY | O_CREAT | O_CLOEXEC;
  if (options.temporary_name.empty()) {
    static std::atomic<std::uint64_t> counter{0};
    tmp = path;
    tmp += ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(counter++);
    flags |= O_EXCL;
  } else {
    tmp = dir / options.temporary_name;
    flags |= O_TRUNC;
  }
  TempFile file(tmp, flags, options.mode);
  std::string gathered;
  const ByteSink sink = [&](std::string_view bytes) {
    if (gathered.size() + bytes.size() <= kGather) {
      if (gathered.capacity() < kGather) gathered.reserve(kGather);
      gathered.append(bytes);
      return;
    }
    file.write(gathered);
    gathered.clear();
    if (bytes.size() >= kGather)
      file.write(bytes);
    else
      gathered.append(bytes);
  };
  produce(sink);
  file.write(gathered);
  file.commit(path);
  sync_directory(dir);
}

void write_file_atomically(const std::filesystem::path& path, std::string_view bytes,
                           const AtomicFileOptions& options) {
  write_file_atomically(
      path, [bytes](const ByteSink& sink) { sink(bytes); }, options);
}

}  // namespace stlrefine
