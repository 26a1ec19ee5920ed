// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors

// libFuzzer harness: a zip of parts as POST /v1/jobs takes it (api/archive.h), on untrusted
// bytes: is_part_archive, zip_inflated_bytes, then read_part_archive with small limits and a
// memory budget that refuses large totals. A refusal must be an ArchiveError with a
// documented reason and the code that reason promises (MalformedStl or BudgetExceeded); the
// parts of an accepted zip must keep every promise of its directory checks: safe unique
// mesh names, at most max_entries, at most max_total_bytes in all, what the budget granted,
// no zip inside a part that is not a .3mf. Seeds: corpus/archive (make_seeds.py),
// dictionary dict/archive.dict.

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <set>
#include <span>
#include <string>
#include <string_view>

#include "api/archive.h"
#include "fuzz/fuzz_check.h"

using namespace stlrefine;

namespace {

constexpr std::string_view kMalformedReasons[] = {"bad_archive",    "encrypted",      "unsafe_name",
                                                  "duplicate_name", "nested_archive", "not_a_mesh",
                                                  "no_parts"};
constexpr std::string_view kBudgetReasons[] = {"too_many_entries", "archive_too_large",
                                               "compression_ratio", "memory_budget"};

bool listed(std::span<const std::string_view> reasons, const std::string& reason) {
  return std::find(reasons.begin(), reasons.end(), reason) != reasons.end();
}

void check_refusal(const api::ArchiveError& e) {
  fuzz::check_refusal(e);
  if (e.code() == ErrorCode::MalformedStl)
    fuzz::check(listed(kMalformedReasons, e.reason()),
                "undocumented malformed reason:", e.reason().c_str());
  else if (e.code() == ErrorCode::BudgetExceeded)
    fuzz::check(listed(kBudgetReasons, e.reason()),
                "undocumented budget reason:", e.reason().c_str());
  else
    fuzz::fail("an archive refusal with another code:", e.what());
  fuzz::check(e.field() == "file", "an archive refusal that does not name the field file");
}

std::string lowercase(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

bool ends_with(const std::string& s, std::string_view end) {
  return s.size() > end.size() && s.compare(s.size() - end.size(), end.size(), end) == 0;
}

// The promises of unsafe_name and mesh_extension, written independently of them.
void check_name(const std::string& name) {
  fuzz::check(!name.empty() && name.front() != '/', "an empty or absolute part name");
  fuzz::check(name.find('\\') == std::string::npos, "a part name with a backslash");
  fuzz::check(!(name.size() >= 2 && name[1] == ':'), "a part name with a drive letter");
  for (const char c : name)
    fuzz::check(static_cast<unsigned char>(c) >= 0x20 && c != 0x7f,
                "a part name with a control character");
  fuzz::check(name != ".." && name.rfind("../", 0) != 0 && name.find("/../") == std::string::npos &&
                  !(name.size() >= 3 && name.compare(name.size() - 3, 3, "/..") == 0),
              "a part name with a .. component");
  const std::string lower = lowercase(name);
  const auto ends = [&](std::string_view ext) { return ends_with(lower, ext); };
  fuzz::check(ends(".stl") || ends(".obj") || ends(".ply") || ends(".3mf"),
              "a part that is not a mesh file by its extension");
}

void read_with(std::span<const std::uint8_t> bytes, api::ArchiveLimits limits,
               std::uint64_t budget) {
  std::uint64_t granted = 0;
  bool asked = false;
  limits.reserve = [&](std::uint64_t total) {
    fuzz::check(!asked, "the budget was asked twice");
    asked = true;
    fuzz::check(total <= limits.max_total_bytes, "asked the budget for more than max_total_bytes");
    if (total > budget) return false;
    granted = total;
    return true;
  };
  try {
    const std::vector<api::ArchivePart> parts = api::read_part_archive(bytes, limits);
    fuzz::check(asked, "parts inflated without asking the budget");
    fuzz::check(!parts.empty() && parts.size() <= limits.max_entries, "part count out of range");
    std::uint64_t total = 0;
    std::set<std::string> names;
    for (const api::ArchivePart& p : parts) {
      check_name(p.name);
      fuzz::check(names.insert(p.name).second, "a part name twice");
      total += p.bytes.size();
      const bool zip = p.bytes.size() >= 4 && p.bytes.compare(0, 4, "PK\3\4") == 0;
      fuzz::check(!zip || ends_with(lowercase(p.name), ".3mf"),
                  "a zip inside the zip was accepted as a part");
    }
    fuzz::check(total <= limits.max_total_bytes, "parts past max_total_bytes");
    fuzz::check(total == granted, "parts inflated to other than what the budget granted");
  } catch (const api::ArchiveError& e) {
    check_refusal(e);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);
  (void)api::is_part_archive(bytes);
  (void)api::zip_inflated_bytes(bytes);
  // The daemon's limits, and the smallest that still take a part (so every budget refusal
  // is reachable from a small input).
  read_with(bytes, api::ArchiveLimits{}, std::uint64_t{64} << 20);
  api::ArchiveLimits small;
  small.max_total_bytes = 16384;
  small.max_entries = 2;
  small.max_ratio = 4;
  read_with(bytes, small, 8192);
  return 0;
}
