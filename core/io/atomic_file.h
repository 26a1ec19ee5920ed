// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <sys/types.h>

#include <filesystem>
#include <functional>
#include <string>
#include <string_view>
#include <system_error>

#include "core/error.h"

namespace stlrefine {

//! Receives the bytes of a file (or an answer), in order, in pieces of any size.
using ByteSink = std::function<void(std::string_view bytes)>;

//! A file that could not be written: code InvalidParameter, reason "cannot_create" (the file
//! cannot be created or put in place), or Internal, "write_failed" (writing or syncing
//! failed midway); field "path", the message naming the file and the system's reason. It
//! keeps the system's error code, so a caller can tell a full disk (ENOSPC, EDQUOT, EFBIG)
//! from other failures.
class FileError : public Error {
 public:
  FileError(ErrorCode code, std::string reason, const std::string& message, std::error_code os)
      : Error(code, std::move(reason), message), os_(os) {
    with_field("path");
  }
  const std::error_code& os_error() const { return os_; }

 private:
  std::error_code os_;
};

struct AtomicFileOptions {
  //! The temporary file's name in the target's directory; empty (default): a unique one,
  //! "<target>.tmp-<pid>-<n>", so concurrent writers in one process never collide. A given
  //! name is opened with O_TRUNC (not O_EXCL): callers that name it own the directory.
  std::string temporary_name;
  //! Permissions of the new file (before the umask).
  mode_t mode = 0666;
};

//! Replaces `path` as a whole: `produce` gives the bytes to the sink it receives (in pieces
//! of any size, gathered into large writes); they go to a temporary file in the same
//! directory, which is fsync'ed, renamed over `path`, and the directory fsync'ed. Readers see
//! the old file or the whole new one, never a part. When anything fails (the temporary file
//! cannot be made, a write fails for want of space, `produce` throws), the temporary file is
//! removed, `path` is left as it was, and the exception propagates: FileError for the file
//! system's failures, whatever `produce` threw otherwise.
void write_file_atomically(const std::filesystem::path& path,
                           const std::function<void(const ByteSink& sink)>& produce,
                           const AtomicFileOptions& options = {});

//! write_file_atomically with bytes already in memory (written as they are, no copy).
void write_file_atomically(const std::filesystem::path& path, std::string_view bytes,
                           const AtomicFileOptions& options = {});

}  // namespace stlrefine
