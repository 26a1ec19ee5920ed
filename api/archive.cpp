// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "api/archive.h"

#include <zip.h>

#include <algorithm>
#include <cctype>
#include <limits>
#include <memory>
#include <set>
#include <system_error>

namespace stlrefine::api {

namespace {

struct ZipClose {
  void operator()(zip_t* z) const { zip_discard(z); }
};
struct FileClose {
  void operator()(zip_file_t* f) const { zip_fclose(f); }
};
using Zip = std::unique_ptr<zip_t, ZipClose>;

bool zip_magic(std::span<const std::uint8_t> b) {
  return b.size() >= 4 && b[0] == 'P' && b[1] == 'K' && b[2] == 3 && b[3] == 4;
}

// libzip refuses to open a zip with a name twice (ZIP_ER_EXISTS) without saying which: the
// central directory's names, read here, tell it.
std::string duplicated_name(std::span<const std::uint8_t> b) {
  const auto u16 = [&](std::size_t at) { return b[at] | (b[at + 1] << 8); };
  const auto u32 = [&](std::size_t at) {
    return static_cast<std::uint32_t>(u16(at)) | (static_cast<std::uint32_t>(u16(at + 2)) << 16);
  };
  if (b.size() < 22) return {};
  std::size_t eocd = b.size() - 22;
  const std::size_t lowest = b.size() > 22 + 65535 ? b.size() - 22 - 65535 : 0;
  while (u32(eocd) != 0x06054b50) {
    if (eocd == lowest) return {};
    --eocd;
  }
  std::size_t at = u32(eocd + 16);
  std::set<std::string> seen;
  for (unsigned i = 0, n = u16(eocd + 10); i < n && at + 46 <= b.size(); ++i) {
    if (u32(at) != 0x02014b50) return {};
    const std::size_t name = u16(at + 28), extra = u16(at + 30), comment = u16(at + 32);
    if (at + 46 + name > b.size()) return {};
    std::string text(reinterpret_cast<const char*>(b.data()) + at + 46, name);
    if (!seen.insert(text).second) return text;
    at += 46 + name + extra + comment;
  }
  return {};
}

// Opened read-only from memory (the bytes outlive the handle); nullptr when not a zip.
Zip open_zip(std::span<const std::uint8_t> bytes, std::string* why, int* code = nullptr) {
  zip_error_t error;
  zip_error_init(&error);
  zip_source_t* source = zip_source_buffer_create(bytes.data(), bytes.size(), 0, &error);
  if (!source) {
    if (why) *why = zip_error_strerror(&error);
    zip_error_fini(&error);
    return nullptr;
  }
  zip_t* z = zip_open_from_source(source, ZIP_RDONLY | ZIP_CHECKCONS, &error);
  if (!z) {
    if (why) *why = zip_error_strerror(&error);
    if (code) *code = zip_error_code_zip(&error);
    zip_source_free(source);
  }
  zip_error_fini(&error);
  return Zip(z);
}

std::string printable(const std::string& name) {
  std::string out;
  for (const char c : name.substr(0, 120))
    out.push_back(static_cast<unsigned char>(c) < 0x20 || c == 0x7f ? '?' : c);
  if (name.size() > 120) out.append("...");
  return out;
}

[[noreturn]] void refuse(ErrorCode code, const char* reason, const std::string& entry,
                         const std::string& why) {
  std::string message =
      entry.empty() ? std::string("the zip ") : "zip entry '" + printable(entry) + "' ";
  message.append(why);
  throw ArchiveError(code, reason, message, entry);
}

bool mesh_extension(const std::string& name) {
  const std::size_t dot = name.rfind('.');
  if (dot == std::string::npos) return false;
  std::string ext = name.substr(dot + 1);
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext == "stl" || ext == "obj" || ext == "ply" || ext == "3mf";
}

bool is_3mf_name(const std::string& name) {
  return name.size() > 4 && std::equal(name.end() - 4, name.end(), ".3mf", [](char a, char b) {
           return std::tolower(static_cast<unsigned char>(a)) == b;
         });
}

bool unsafe_name(const std::string& name) {
  if (name.empty() || name.front() == '/' || name.find('\\') != std::string::npos) return true;
  if (name.size() >= 2 && name[1] == ':') return true;  // C:...
  for (const char c : name)
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) return true;
  std::size_t start = 0;
  while (start <= name.size()) {
    const std::size_t slash = std::min(name.find('/', start), name.size());
    if (name.compare(start, slash - start, "..") == 0 && slash - start == 2) return true;
    start = slash + 1;
  }
  return false;
}

}  // namespace

bool is_part_archive(std::span<const std::uint8_t> bytes) {
  if (!zip_magic(bytes)) return false;
  int code = 0;
  const Zip z = open_zip(bytes, nullptr, &code);
  if (!z) return code == ZIP_ER_EXISTS;  // a name twice: refused by read_part_archive
  return zip_name_locate(z.get(), "3D/3dmodel.model", ZIP_FL_NOCASE) < 0 &&
         zip_name_locate(z.get(), "[Content_Types].xml", ZIP_FL_NOCASE) < 0;
}

namespace {
std::uint64_t saturated(std::uint64_t a, std::uint64_t b) {
  return b > std::numeric_limits<std::uint64_t>::max() - a
             ? std::numeric_limits<std::uint64_t>::max()
             : a + b;
}
}  // namespace

std::uint64_t zip_inflated_bytes(std::span<const std::uint8_t> bytes) {
  if (!zip_magic(bytes)) return 0;
  const Zip z = open_zip(bytes, nullptr);
  if (!z) return 0;
  const zip_int64_t n = zip_get_num_entries(z.get(), 0);
  std::uint64_t total = 0;
  for (zip_int64_t i = 0; i < n; ++i) {
    zip_stat_t st;
    zip_stat_init(&st);
    if (zip_stat_index(z.get(), static_cast<zip_uint64_t>(i), 0, &st) != 0 ||
        !(st.valid & ZIP_STAT_SIZE))
      continue;
    total = saturated(total, st.size);
  }
  return total;
}

std::vector<ArchivePart> read_part_archive(std::span<const std::uint8_t> bytes,
                                           const ArchiveLimits& limits) {
  std::string why;
  int code = 0;
  const Zip z = open_zip(bytes, &why, &code);
  if (!z && code == ZIP_ER_EXISTS)
    refuse(ErrorCode::MalformedStl, "duplicate_name", duplicated_name(bytes),
           "is in the zip twice");
  if (!z) refuse(ErrorCode::MalformedStl, "bad_archive", "", "cannot be read: " + why);
  const zip_int64_t n = zip_get_num_entries(z.get(), 0);
  if (n < 0 || static_cast<std::uint64_t>(n) > 4 * limits.max_entries)
    refuse(ErrorCode::BudgetExceeded, "too_many_entries", "",
           "has " + std::to_string(n) + " entries; at most " + std::to_string(limits.max_entries) +
               " mesh files are taken");
  // Every entry checked on the directory first, so nothing is inflated from a zip that would
  // be refused.
  struct Entry {
    zip_uint64_t index;
    std::string name;
    zip_uint64_t size;
  };
  std::vector<Entry> entries;
  std::set<std::string> names;
  std::uint64_t total = 0;
  for (zip_uint64_t i = 0; i < static_cast<zip_uint64_t>(n); ++i) {
    zip_stat_t st;
    zip_stat_init(&st);
    if (zip_stat_index(z.get(), i, ZIP_FL_ENC_GUESS, &st) != 0 || !(st.valid & ZIP_STAT_NAME) ||
        !(st.valid & ZIP_STAT_SIZE) || !(st.valid & ZIP_STAT_COMP_SIZE))
      refuse(ErrorCode::MalformedStl, "bad_archive", "",
             "has an unreadable directory entry (" + std::to_string(i) + ")");
    const std::string name = st.name;
    if (unsafe_name(name))
      refuse(ErrorCode::MalformedStl, "unsafe_name", name,
             "has an absolute name, a '..' component, a backslash or a control character");
    if (!names.insert(name).second)
      refuse(ErrorCode::MalformedStl, "duplicate_name", name, "is in the zip twice");
    if (name.back() == '/' || name.rfind("__MACOSX/", 0) == 0) continue;  // no content
    if ((st.valid & ZIP_STAT_ENCRYPTION_METHOD) && st.encryption_method != ZIP_EM_NONE)
      refuse(ErrorCode::MalformedStl, "encrypted", name, "is encrypted; send it unencrypted");
    if (!mesh_extension(name))
      refuse(ErrorCode::MalformedStl, "not_a_mesh", name,
             "is not a mesh file (.stl, .obj, .ply or .3mf)");
    if (entries.size() >= limits.max_entries)
      refuse(ErrorCode::BudgetExceeded, "too_many_entries", name,
             "is past the " + std::to_string(limits.max_entries) + " mesh files a zip may hold");
    if (st.size > limits.max_total_bytes - std::min(total, limits.max_total_bytes))
      refuse(ErrorCode::BudgetExceeded, "archive_too_large", name,
             "takes the zip's content past " + std::to_string(limits.max_total_bytes) +
                 " bytes, the most this server takes in one upload");
    if (st.size > 4096 &&
        static_cast<double>(st.size) >
            limits.max_ratio * static_cast<double>(std::max<zip_uint64_t>(st.comp_size, 1)))
      refuse(ErrorCode::BudgetExceeded, "compression_ratio", name,
             "inflates " + std::to_string(st.size) + " bytes from " + std::to_string(st.comp_size) +
                 " (over " + std::to_string(static_cast<int>(limits.max_ratio)) +
                 ":1): refused as a zip bomb");
    total += st.size;
    entries.push_back({i, name, st.size});
  }
  if (entries.empty())
    refuse(ErrorCode::MalformedStl, "no_parts", "", "has no mesh file (.stl, .obj, .ply, .3mf)");
  if (limits.reserve && !limits.reserve(total))
    refuse(ErrorCode::BudgetExceeded, "memory_budget", "",
           "inflates to " + std::to_string(total) +
               " bytes, more than the memory budget has "
               "free now");

  std::vector<ArchivePart> parts;
  for (const Entry& e : entries) {
    std::unique_ptr<zip_file_t, FileClose> file(zip_fopen_index(z.get(), e.index, 0));
    if (!file)
      refuse(ErrorCode::MalformedStl, "bad_archive", e.name,
             std::string("cannot be opened: ") + zip_strerror(z.get()));
    // The declared size and not a byte more: a directory that lies is refused, not obeyed.
    std::string data(e.size, '\0');
    zip_uint64_t got = 0;
    while (got < e.size) {
      const zip_int64_t r = zip_fread(file.get(), data.data() + got, e.size - got);
      if (r <= 0) break;
      got += static_cast<zip_uint64_t>(r);
    }
    char extra = 0;
    if (got != e.size || zip_fread(file.get(), &extra, 1) != 0)
      refuse(ErrorCode::MalformedStl, "bad_archive", e.name,
             "does not inflate to its declared " + std::to_string(e.size) +
                 " bytes (or fails "
                 "its CRC)");
    const auto content = std::span(reinterpret_cast<const std::uint8_t*>(data.data()), data.size());
    if (zip_magic(content) && !is_3mf_name(e.name))
      refuse(ErrorCode::MalformedStl, "nested_archive", e.name,
             "is itself a zip; zips inside the zip are not opened");
    parts.push_back({e.name, std::move(data)});
  }
  return parts;
}

void write_zip_of_files(const std::filesystem::path& out, const std::vector<ZipFile>& files) {
  int code = 0;
  zip_t* z = zip_open(out.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &code);
  const auto fail = [](zip_error_t* error, const std::string& what) {
    const int sys = zip_error_code_system(error);
    if (zip_error_system_type(error) == ZIP_ET_SYS && sys != 0)
      throw std::system_error(sys, std::generic_category(), what);
    throw Error(ErrorCode::Internal, "zip", what + ": " + zip_error_strerror(error));
  };
  if (!z) {
    zip_error_t error;
    zip_error_init_with_code(&error, code);
    fail(&error, "cannot create " + out.string());
  }
  Zip owned(z);
  for (const ZipFile& f : files) {
    zip_source_t* source = zip_source_file(z, f.path.c_str(), 0, -1);
    if (!source) fail(zip_get_error(z), "cannot read " + f.path.string());
    const zip_int64_t index = zip_file_add(z, f.name.c_str(), source, ZIP_FL_ENC_UTF_8);
    if (index < 0) {
      zip_source_free(source);
      fail(zip_get_error(z), "cannot add " + f.name);
    }
    zip_set_file_compression(z, static_cast<zip_uint64_t>(index), ZIP_CM_STORE, 0);
  }
  if (zip_close(z) != 0) fail(zip_get_error(z), "cannot write " + out.string());
  (void)owned.release();  // closed
}

}  // namespace stlrefine::api
