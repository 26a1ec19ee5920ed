// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "api/zip.h"

#include <zip.h>

#include <cstdio>
#include <memory>

#include "core/error.h"

namespace stlrefine::api {

namespace {

Error zip_failure(const std::string& what, zip_error_t* error) {
  return Error(ErrorCode::Internal, "zip", what + ": " + zip_error_strerror(error));
}

struct SourceFree {
  void operator()(zip_source_t* s) const { zip_source_free(s); }
};

}  // namespace

std::string make_zip(const std::vector<ZipEntry>& entries) {
  zip_error_t error;
  zip_error_init(&error);
  // The archive is written into a growing buffer source, kept alive past zip_close.
  std::unique_ptr<zip_source_t, SourceFree> buffer(zip_source_buffer_create(nullptr, 0, 0, &error));
  if (!buffer) throw zip_failure("zip_source_buffer_create", &error);
  zip_t* archive = zip_open_from_source(buffer.get(), ZIP_TRUNCATE, &error);
  if (!archive) throw zip_failure("zip_open_from_source", &error);
  zip_source_keep(buffer.get());

  auto fail = [&](const std::string& what) {
    Error e = zip_failure(what, zip_get_error(archive));
    zip_discard(archive);
    return e;
  };
  for (const ZipEntry& entry : entries) {
    zip_source_t* data = zip_source_buffer(archive, entry.data.data(), entry.data.size(), 0);
    if (!data) throw fail("zip_source_buffer");
    const zip_int64_t index = zip_file_add(archive, entry.name.c_str(), data, ZIP_FL_ENC_UTF_8);
    if (index < 0) {
      zip_source_free(data);
      throw fail("zip_file_add " + entry.name);
    }
    if (zip_set_file_compression(archive, static_cast<zip_uint64_t>(index),
                                 entry.deflate ? ZIP_CM_DEFLATE : ZIP_CM_STORE,
                                 entry.deflate ? 1 : 0) != 0)
      throw fail("zip_set_file_compression");
  }
  if (zip_close(archive) != 0) throw fail("zip_close");

  zip_source_t* src = buffer.get();
  if (zip_source_open(src) != 0) throw zip_failure("zip_source_open", zip_source_error(src));
  std::string out;
  if (zip_source_seek(src, 0, SEEK_END) != 0) {
    zip_source_close(src);
    throw zip_failure("zip_source_seek", zip_source_error(src));
  }
  const zip_int64_t size = zip_source_tell(src);
  zip_source_seek(src, 0, SEEK_SET);
  out.resize(static_cast<std::size_t>(size < 0 ? 0 : size));
  const zip_int64_t read = zip_source_read(src, out.data(), out.size());
  zip_source_close(src);
  if (read != size) throw Error(ErrorCode::Internal, "zip", "reading the archive back failed");
  return out;
}

}  // namespace stlrefine::api
