// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// What the round-5 job tests (parts, event streams, callback keys) share: a daemon with
// jobs, parts to upload (boxes as STL and 3MF, forms, zips), and waiting for a job's end.

#include <httplib.h>

#include <array>
#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "server/daemon.h"

namespace stlrefine::test {

//! Strings joined by append (GCC 12 warns falsely, -Wrestrict, on "literal" + std::string).
template <class... T>
std::string cat(const T&... parts) {
  std::string s;
  (s.append(parts), ...);
  return s;
}

std::filesystem::path fresh_job_dir(const std::string& name);
server::DaemonConfig jobs_config(const std::filesystem::path& dir);

inline std::span<const std::uint8_t> bytes_of(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

//! An axis-aligned cube of side s, shifted by dx along x: corners and triangles.
struct Box {
  std::vector<std::array<float, 3>> v;
  std::vector<std::array<int, 3>> t;
};
Box box(float s, float dx = 0);
std::string stl_of(const Box& b);
std::string three_mf(const std::vector<std::pair<std::string, Box>>& objects,
                     const std::string& unit = "millimeter");

//! A multipart form with one `file` part.
std::string form_file(const std::string& filename, const std::string& content);
std::string form_type();

//! The job's JSON once it has ended (a test failure after 60 s).
nlohmann::json wait_job(httplib::Client& c, const std::string& location);

}  // namespace stlrefine::test

namespace stlrefine::test {

//! A zip written byte by byte (stored entries unless `deflated_size` is set), so tests can
//! make what no zip library writes: duplicate names, traversal names, encrypted flags,
//! sizes that lie.
struct RawZipEntry {
  std::string name;
  std::string data;
  bool encrypted = false;
  //! Set: the entry claims deflate, this uncompressed size, and `data` as its compressed bytes.
  std::uint32_t claimed_size = 0;
};
std::string raw_zip(const std::vector<RawZipEntry>& entries);

}  // namespace stlrefine::test
