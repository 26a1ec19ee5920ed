// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// A 3MF package (libzip): the zip's directory is checked first (parts, declared sizes);
// _rels/.rels names the model part; that part is inflated in chunks straight into the
// streaming model parser (threemf_model.h), counting the bytes it really inflates to
// against a cap from the package's own size (kMax3mfInflateRatio), whatever the directory
// declared. Replaces Debian's
// lib3mf 1.8.1 for reading, which leaked every zip entry it opened (~800 bytes of daemon
// RSS per request: bench/results-issue19-s5-tmf-web.md).

#include <zip.h>

#include <algorithm>
#include <charconv>
#include <memory>
#include <string>
#include <vector>

#include "core/io/mesh_formats.h"
#include "core/io/reader_util.h"
#include "core/io/threemf_model.h"
#include "core/io/threemf_xml.h"

namespace stlrefine {

namespace {

using io_detail::malformed;

constexpr std::string_view kModelRelationship =
    "http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel";
constexpr std::string_view kRelationshipsNs =
    "http://schemas.openxmlformats.org/package/2006/relationships";
// _rels/.rels names a few parts; a larger one is not a 3MF's.
constexpr std::uint64_t kMaxRelsBytes = 1 << 20;

Error not_3mf(const std::string& message) {
  return malformed("not_3mf", message).at_byte(0);
}

struct ZipCloser {
  void operator()(zip_t* z) const { zip_discard(z); }
};
struct ZipFileCloser {
  void operator()(zip_file_t* f) const { zip_fclose(f); }
};

std::unique_ptr<zip_t, ZipCloser> open_zip(std::span<const std::uint8_t> bytes) {
  zip_error_t error;
  zip_error_init(&error);
  zip_source_t* source = zip_source_buffer_create(bytes.data(), bytes.size(), 0, &error);
  if (!source) throw Error(ErrorCode::Internal, "internal", "libzip: cannot wrap the buffer");
  zip_t* archive = zip_open_from_source(source, ZIP_RDONLY, &error);
  if (!archive) {
    zip_source_free(source);
    const std::string why = zip_error_strerror(&error);
    zip_error_fini(&error);
    throw not_3mf("this starts like a zip (3MF) but is not a readable zip: " + why);
  }
  zip_error_fini(&error);
  return std::unique_ptr<zip_t, ZipCloser>(archive);
}

//! Refuses, from the directory alone, a package of too many parts or whose parts declare
//! more than `limit` bytes: a bomb that tells the truth is refused before any inflating.
void check_directory(zip_t* archive, std::uint64_t limit) {
  const zip_int64_t entries = zip_get_num_entries(archive, 0);
  // Every entry costs libzip memory and time; a model, its relationships, content types,
  // thumbnails and a few attachments fit many times over.
  if (entries > kMax3mfParts)
    throw malformed("too_large", "the 3MF has " + std::to_string(entries) + " parts, more than " +
                                     std::to_string(kMax3mfParts))
        .at_byte(0);
  std::uint64_t total = 0;
  for (zip_int64_t i = 0; i < entries; ++i) {
    zip_stat_t st;
    zip_stat_init(&st);
    // Saturating: a ZIP64 entry may declare up to 2^64 - 1 bytes, which would wrap total.
    if (zip_stat_index(archive, static_cast<zip_uint64_t>(i), 0, &st) == 0 &&
        (st.valid & ZIP_STAT_SIZE))
      total = st.size > limit - total ? limit + 1 : total + st.size;  // total <= limit here
    if (total > limit)
      throw malformed("too_large",
                      "the 3MF's parts inflate to more than " + std::to_string(limit) + " bytes")
          .at_byte(0);
  }
}

//! Inflates part `name` in chunks into `sink(data, size, last)`, counting what it really
//! inflates to against `budget` (decremented; `limit` is the cap a refusal quotes).
template <class Sink>
void inflate(zip_t* archive, const std::string& name, std::uint64_t& budget, std::uint64_t limit,
             const char* why, Sink sink) {
  const zip_int64_t index = zip_name_locate(archive, name.c_str(), ZIP_FL_NOCASE);
  if (index < 0) throw not_3mf("the package has no part " + name);
  std::unique_ptr<zip_file_t, ZipFileCloser> file(
      zip_fopen_index(archive, static_cast<zip_uint64_t>(index), 0));
  if (!file) throw not_3mf("the part " + name + " cannot be opened: " + zip_strerror(archive));
  std::vector<char> chunk(std::size_t{1} << 16);
  for (;;) {
    const zip_int64_t n = zip_fread(file.get(), chunk.data(), chunk.size());
    if (n < 0) throw not_3mf("the part " + name + " is corrupt: " + zip_file_strerror(file.get()));
    if (static_cast<std::uint64_t>(n) > budget)
      throw malformed("too_large", "the 3MF's part " + name + " inflates to more than " +
                                       std::to_string(limit) + " bytes (" + why + ")")
          .at_byte(0);
    budget -= static_cast<std::uint64_t>(n);
    sink(chunk.data(), static_cast<std::size_t>(n), n == 0);
    if (n == 0) return;
  }
}

//! "%20" and the like in a relationship's target.
std::string percent_decoded(std::string_view s) {
  std::string out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    unsigned value = 0;
    if (s[i] == '%' && i + 2 < s.size() &&
        std::from_chars(s.data() + i + 1, s.data() + i + 3, value, 16).ptr == s.data() + i + 3) {
      out.push_back(static_cast<char>(value));
      i += 2;
    } else {
      out.push_back(s[i]);
    }
  }
  return out;
}

//! The first 3D model relationship's target in _rels/.rels.
class RootRelationships : public io_detail::XmlHandler {
 public:
  void start(std::string_view ns, std::string_view name,
             const io_detail::XmlAttributes& attrs) override {
    if (ns != kRelationshipsNs || name != "Relationship" || !target.empty()) return;
    const char* type = attrs.find("Type");
    const char* to = attrs.find("Target");
    if (type && to && type == kModelRelationship) target = to;
  }
  void end(std::string_view, std::string_view) override {}
  std::string target;
};

std::string model_part_name(zip_t* archive, std::uint64_t& budget) {
  const std::string rels = "_rels/.rels";
  if (zip_name_locate(archive, rels.c_str(), ZIP_FL_NOCASE) < 0)
    throw not_3mf("the zip has no _rels/.rels: not a 3MF package");
  RootRelationships handler;
  io_detail::HardenedXml xml(handler, rels);
  std::uint64_t rels_budget = std::min(budget, kMaxRelsBytes);
  const std::uint64_t before = rels_budget;
  inflate(archive, rels, rels_budget, kMaxRelsBytes, "the cap on a 3MF's relationships",
          [&](const char* data, std::size_t size, bool last) { xml.feed(data, size, last); });
  budget -= before - rels_budget;
  if (handler.target.empty())
    throw not_3mf("_rels/.rels names no 3D model part (relationship type " +
                  std::string(kModelRelationship) + ")");
  // Targets of the package's root relationships are package paths ("/3D/3dmodel.model").
  std::string name = percent_decoded(handler.target);
  while (!name.empty() && name.front() == '/') name.erase(0, 1);
  if (name.empty() || zip_name_locate(archive, name.c_str(), ZIP_FL_NOCASE) < 0)
    throw not_3mf("_rels/.rels names the model part " + io_detail::quoted(handler.target) +
                  ", which the package does not hold");
  return name;
}

}  // namespace

MeshInput read_3mf(std::span<const std::uint8_t> bytes, const StlReadOptions& options) {
  options.validate();
  const auto archive = open_zip(bytes);
  const std::uint64_t limit =
      std::min(kMax3mfUncompressedBytes,
               std::max(kMax3mfInflateFloor, kMax3mfInflateRatio * std::uint64_t{bytes.size()}));
  check_directory(archive.get(), limit);
  std::uint64_t budget = limit;
  const std::string part = model_part_name(archive.get(), budget);
  io_detail::ThreeMfModel model(options, part);
  inflate(archive.get(), part, budget, limit,
          "the 3MF's parts may inflate to 100 times the package's size, 64 MiB at least",
          [&](const char* data, std::size_t size, bool last) { model.feed(data, size, last); });
  return model.finish();
}

}  // namespace stlrefine
