// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// A zip of mesh files (STL, OBJ, PLY, 3MF) uploaded as one job with one result per part:
// told from a 3MF package (also a zip) by its entries, and read with libzip under limits
// checked on the zip's directory before anything is inflated.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "core/error.h"

namespace stlrefine::api {

struct ArchiveLimits {
  //! Bytes all entries may inflate to (the declared sizes, checked before inflating, and
  //! the bytes really inflated).
  std::uint64_t max_total_bytes = std::uint64_t{256} << 20;
  std::size_t max_entries = 100;  //!< mesh entries (and entries in all: 4 times this)
  //! Inflated size over compressed size of one entry at most (zip bombs reach 1000:1; mesh
  //! files deflate 2-10:1).
  double max_ratio = 100;
  //! Called with the declared total before anything is inflated (the daemon reserves it
  //! in its memory budget); false refuses the archive (reason memory_budget).
  std::function<bool(std::uint64_t bytes)> reserve;
};

//! One mesh file of the archive.
struct ArchivePart {
  std::string name;  //!< its path in the archive
  std::string bytes;
  //! An object of a 3MF written as a binary STL in mm (its unit already applied): refined
  //! with units=mm (server/job_parts.cpp).
  bool in_mm = false;
};

//! A refusal of an archive that names the entry (empty when the archive as a whole):
//! Error(MalformedStl) with reason bad_archive, encrypted, unsafe_name, duplicate_name,
//! nested_archive, not_a_mesh or no_parts; Error(BudgetExceeded) with reason
//! too_many_entries, archive_too_large, compression_ratio or memory_budget. Field "file".
class ArchiveError : public Error {
 public:
  ArchiveError(ErrorCode code, std::string reason, const std::string& message, std::string entry)
      : Error(code, std::move(reason), message), entry_(std::move(entry)) {
    with_field("file");
  }
  const std::string& entry() const { return entry_; }

 private:
  std::string entry_;
};

//! Whether `bytes` are a zip ("PK\3\4") that is not a 3MF package (no 3D/3dmodel.model
//! and no [Content_Types].xml entry): a zip of parts. An unreadable zip is not.
bool is_part_archive(std::span<const std::uint8_t> bytes);

//! The archive's mesh entries in the order of its directory. Directories and macOS's
//! `__MACOSX/` resource entries are skipped; every other entry must be a mesh file by its
//! extension (.stl, .obj, .ply, .3mf, any case), with a relative name without `..`,
//! backslashes or control characters, not encrypted, not another zip (a .3mf is one by
//! design), named once. \throw ArchiveError
std::vector<ArchivePart> read_part_archive(std::span<const std::uint8_t> bytes,
                                           const ArchiveLimits& limits);

//! The bytes a zip's entries (a 3MF package's parts) declare they inflate to, all added
//! (saturating); 0 when `bytes` are not a readable zip. Read from the directory: nothing is
//! inflated.
std::uint64_t zip_inflated_bytes(std::span<const std::uint8_t> bytes);

//! A file to bundle: its name in the zip and where it is.
struct ZipFile {
  std::string name;
  std::filesystem::path path;
};

//! Writes the files as a zip at `out`, stored (meshes and contours are large: no time spent
//! deflating), read from disk as they are written (never whole in memory). libzip writes a
//! temporary file beside `out` and renames it at the end.
//! 	hrow std::system_error with the system's code when a write fails (ENOSPC...);
//! Error(Internal) for other libzip failures.
void write_zip_of_files(const std::filesystem::path& out, const std::vector<ZipFile>& files);

}  // namespace stlrefine::api
