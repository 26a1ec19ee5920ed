// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/http_upload.h"

#include <string.h>  // memmem

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <utility>
#include <vector>

#include "core/error.h"
#include "server/request_head.h"

namespace stlrefine::server {

namespace {

// A part's header block (in memory already: the bound is on the scan). Long enough for a
// 1 MB file name, which is then cut to kMaxNameBytes.
constexpr std::size_t kMaxPartHead = 2 << 20;
constexpr std::size_t kMaxNameBytes = 240;

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

// `value; a=b; c="d \" e"` -> the value and its parameters (names lower-cased). Malformed
// pieces are skipped: a name that cannot be read is no name.
std::pair<std::string, std::vector<std::pair<std::string, std::string>>> header_params(
    std::string_view text) {
  std::vector<std::pair<std::string, std::string>> params;
  std::size_t i = text.find(';');
  const std::string value = lower(trim(text.substr(0, i)));
  while (i != std::string_view::npos && i < text.size()) {
    ++i;  // past ';'
    while (i < text.size() && (text[i] == ' ' || text[i] == '\t')) ++i;
    const std::size_t eq = text.find('=', i);
    const std::size_t semi = text.find(';', i);
    if (eq == std::string_view::npos || (semi != std::string_view::npos && semi < eq)) {
      i = semi;
      continue;
    }
    const std::string name = lower(trim(text.substr(i, eq - i)));
    std::string v;
    i = eq + 1;
    while (i < text.size() && (text[i] == ' ' || text[i] == '\t')) ++i;
    if (i < text.size() && text[i] == '"') {
      for (++i; i < text.size() && text[i] != '"'; ++i) {
        if (text[i] == '\\' && i + 1 < text.size()) ++i;
        v.push_back(text[i]);
      }
      i = text.find(';', i);
    } else {
      const std::size_t end = text.find(';', i);
      v = std::string(trim(text.substr(i, end == std::string_view::npos ? end : end - i)));
      i = end;
    }
    params.emplace_back(name, std::move(v));
  }
  return {value, std::move(params)};
}

const std::string* param(const std::vector<std::pair<std::string, std::string>>& params,
                         std::string_view name) {
  for (const auto& [n, v] : params)
    if (n == name) return &v;
  return nullptr;
}

// RFC 8187 `UTF-8''percent%20encoded` -> the bytes; nullopt for another charset.
std::optional<std::string> ext_value(std::string_view v) {
  const std::size_t q = v.find('\'');
  if (q == std::string_view::npos || lower(v.substr(0, q)) != "utf-8") return std::nullopt;
  const std::size_t q2 = v.find('\'', q + 1);
  if (q2 == std::string_view::npos) return std::nullopt;
  std::string out;
  for (std::size_t i = q2 + 1; i < v.size(); ++i) {
    if (v[i] == '%' && i + 2 < v.size() && hex_value(v[i + 1]) >= 0 && hex_value(v[i + 2]) >= 0) {
      out.push_back(static_cast<char>(hex_value(v[i + 1]) * 16 + hex_value(v[i + 2])));
      i += 2;
    } else {
      out.push_back(v[i]);
    }
  }
  return out;
}

// The filename of Content-Disposition parameters (filename* wins, RFC 6266 4.3).
std::string disposition_filename(const std::vector<std::pair<std::string, std::string>>& params) {
  if (const std::string* ext = param(params, "filename*"))
    if (std::optional<std::string> v = ext_value(*ext)) return *v;
  const std::string* plain = param(params, "filename");
  return plain ? *plain : std::string();
}

api::Problem upload_problem(std::string field, std::string detail, const char* reason) {
  api::Problem p = api::bad_request("bad-request", std::move(detail));
  p.field = std::move(field);
  p.extensions["reason"] = reason;
  return p;
}

// Where `needle` first is in hay[from, limit), or npos (memmem: a body can be 256 MiB).
std::size_t find_in(std::string_view hay, std::string_view needle, std::size_t from,
                    std::size_t limit = std::string_view::npos) {
  limit = std::min(limit, hay.size());
  if (from >= limit) return std::string_view::npos;
  const void* at = ::memmem(hay.data() + from, limit - from, needle.data(), needle.size());
  return at ? static_cast<std::size_t>(static_cast<const char*>(at) - hay.data())
            : std::string_view::npos;
}

// Length of the valid UTF-8 sequence at s[i], or 0.
std::size_t utf8_length(std::string_view s, std::size_t i) {
  const auto c = static_cast<unsigned char>(s[i]);
  std::size_t n = c < 0x80 ? 1 : (c >> 5) == 6 ? 2 : (c >> 4) == 14 ? 3 : (c >> 3) == 30 ? 4 : 0;
  if (n == 0 || i + n > s.size()) return 0;
  for (std::size_t k = 1; k < n; ++k)
    if ((static_cast<unsigned char>(s[i + k]) & 0xC0) != 0x80) return 0;
  // Overlong forms and surrogates are not characters.
  const auto c1 = static_cast<unsigned char>(s[i + (n > 1 ? 1 : 0)]);
  if ((n == 2 && c < 0xC2) || (n == 3 && c == 0xE0 && c1 < 0xA0) ||
      (n == 3 && c == 0xED && c1 >= 0xA0) || (n == 4 && c == 0xF0 && c1 < 0x90) ||
      (n == 4 && (c > 0xF4 || (c == 0xF4 && c1 >= 0x90))))
    return 0;
  return n;
}

}  // namespace

std::optional<std::string> multipart_boundary(std::string_view content_type) {
  auto [type, params] = header_params(content_type);
  if (type != "multipart/form-data") return std::nullopt;
  const std::string* b = param(params, "boundary");
  if (!b || b->empty() || b->size() > 70 || b->back() == ' ') return std::string();
  // RFC 2046 bchars: no controls, no quotes the header could not carry.
  for (const char ch : *b) {
    const auto c = static_cast<unsigned char>(ch);
    if (c < 0x20 || c >= 0x7f) return std::string();
  }
  return *b;
}

std::optional<api::Problem> read_upload(const HttpRequest& req, Upload& out) {
  out = Upload{req.body, {}};
  const std::string content_type = req.header("Content-Type");
  const std::optional<std::string> boundary = multipart_boundary(content_type);
  // `filename=` in the query: any body's name unless the body names itself.
  std::string query_name;
  int query_names = 0;
  try {
    for (const auto& [name, value] : req.parameters())
      if (name == "filename") {
        query_name = value;
        ++query_names;
      }
  } catch (const Error& e) {  // precheck parsed it already; a handler called directly may not
    return api::problem_from_error(e);
  }
  if (query_names > 1) return upload_problem("filename", "filename is given twice", "duplicate");
  if (!boundary) {
    // A raw body: its name in a Content-Disposition header, else the query's.
    if (req.has_header("Content-Disposition"))
      out.name = upload_name(
          disposition_filename(header_params(req.header("Content-Disposition")).second));
    if (out.name.empty()) out.name = upload_name(query_name);
    return std::nullopt;
  }
  if (boundary->empty())
    return upload_problem("Content-Type",
                          "multipart/form-data needs a boundary of 1 to 70 characters",
                          "bad_boundary");
  const std::string_view body = req.body;
  const std::string delimiter = "--" + *boundary;
  const std::string inner = "\r\n" + delimiter;
  // The first delimiter opens the body or follows a preamble's CRLF.
  std::size_t pos;
  if (body.substr(0, delimiter.size()) == delimiter) {
    pos = delimiter.size();
  } else {
    const std::size_t at = find_in(body, inner, 0);
    if (at == std::string_view::npos)
      return upload_problem(
          "file", "the multipart body has no part: no boundary '" + *boundary + "'", "no_part");
    pos = at + inner.size();
  }
  bool have_file = false;
  for (;;) {
    // After a delimiter: "--" closes the body; else optional blanks, then CRLF.
    if (body.substr(pos, 2) == "--") break;
    while (pos < body.size() && (body[pos] == ' ' || body[pos] == '\t')) ++pos;
    if (body.substr(pos, 2) != "\r\n")
      return upload_problem("file", "a multipart boundary line does not end with CRLF",
                            "malformed_multipart");
    pos += 2;
    const std::size_t head_end = find_in(body, "\r\n\r\n", pos, pos + kMaxPartHead + 4);
    // A part without headers starts with the blank line itself.
    std::string_view head;
    std::size_t content_start;
    if (body.substr(pos, 2) == "\r\n") {
      content_start = pos + 2;
    } else if (head_end == std::string_view::npos) {
      return upload_problem("file", "a multipart part's headers do not end (or exceed 2 MiB)",
                            "malformed_multipart");
    } else {
      head = body.substr(pos, head_end + 2 - pos);  // each line with its CRLF
      content_start = head_end + 4;
    }
    const std::size_t content_end = find_in(body, inner, content_start);
    if (content_end == std::string_view::npos)
      return upload_problem("file", "the multipart body ends without its closing boundary",
                            "unterminated_multipart");
    // Part headers: Content-Disposition names the field; Content-Type is not needed.
    std::string field, filename;
    bool disposition = false, named_file = false;
    for (std::size_t l = 0; l < head.size();) {
      const std::size_t eol = head.find("\r\n", l);
      const std::string_view line = head.substr(l, eol - l);
      l = eol + 2;
      const std::size_t colon = line.find(':');
      if (colon == std::string_view::npos || colon == 0)
        return upload_problem("file", "a multipart part has a header line without a name",
                              "malformed_multipart");
      if (!equals_ignore_case(line.substr(0, colon), "Content-Disposition")) continue;
      auto [kind, params] = header_params(line.substr(colon + 1));
      if (kind != "form-data" || disposition)
        return upload_problem("file", "a multipart part needs one Content-Disposition: form-data",
                              "malformed_multipart");
      disposition = true;
      const std::string* name = param(params, "name");
      field = name ? *name : std::string();
      named_file = param(params, "filename") || param(params, "filename*");
      filename = disposition_filename(params);
    }
    if (!disposition)
      return upload_problem("file", "a multipart part has no Content-Disposition: form-data",
                            "malformed_multipart");
    if (field != "file") {
      // Parameters are read before the upload (and a refused one is never sent): they go
      // in the query string, and a form field would be a second, conflicting place.
      const std::string shown = upload_name(field).substr(0, 64);
      return upload_problem(
          shown.empty() ? "file" : shown,
          named_file
              ? "the file goes in the form field 'file', not '" + shown + "'"
              : "form field '" + shown + "' is not accepted: give parameters in the query string",
          "unexpected_field");
    }
    if (have_file)
      return upload_problem("file", "the form has more than one 'file' part; upload one file",
                            "duplicate_file");
    have_file = true;
    out.bytes = body.substr(content_start, content_end - content_start);
    out.name = upload_name(filename.empty() ? query_name : filename);
    pos = content_end + inner.size();
  }
  if (!have_file)
    return upload_problem("file", "the form has no 'file' part (curl -F file=@part.stl)",
                          "missing_file");
  return std::nullopt;
}

std::string upload_name(std::string_view raw) {
  // Browsers (and old IE) may send a whole path: keep the last component.
  const std::size_t sep = raw.find_last_of("/\\");
  if (sep != std::string_view::npos) raw.remove_prefix(sep + 1);
  std::string out;
  for (std::size_t i = 0; i < raw.size();) {
    const std::size_t n = utf8_length(raw, i);
    if (n == 0) {
      ++i;  // not UTF-8: dropped
      continue;
    }
    const auto c = static_cast<unsigned char>(raw[i]);
    if (n == 1 && (c < 0x20 || c == 0x7f)) {
      ++i;
      continue;
    }
    if (out.size() + n > kMaxNameBytes) break;
    out.append(raw.substr(i, n));
    i += n;
  }
  // No hidden names, no "..", no padding.
  while (!out.empty() && (out.front() == '.' || out.front() == ' ')) out.erase(0, 1);
  while (!out.empty() && (out.back() == '.' || out.back() == ' ')) out.pop_back();
  return out;
}

std::string download_stem(std::string_view name) {
  const std::size_t dot = name.rfind('.');
  if (dot != std::string_view::npos && dot > 0 && name.size() - dot <= 6)
    name = name.substr(0, dot);
  return name.empty() ? std::string("part") : std::string(name);
}

std::string content_disposition(std::string_view stem, std::string_view suffix) {
  std::string full(stem);
  full.append(suffix);
  std::string ascii;
  bool plain = true;
  for (const char ch : full) {
    const auto c = static_cast<unsigned char>(ch);
    const bool keep = std::isalnum(c) || c == '-' || c == '_' || c == '.' || c == ' ' || c == '(' ||
                      c == ')' || c == '+' || c == ',';
    if (!keep) plain = false;
    // A multi-byte character is one '_', not one per byte.
    if (!keep && (c & 0xC0) == 0x80) continue;
    ascii.push_back(keep ? ch : '_');
  }
  std::string header = "attachment; filename=\"";
  header.append(ascii).push_back('"');
  if (!plain) {
    // RFC 8187 attr-char, everything else percent-encoded.
    header.append("; filename*=UTF-8''");
    static constexpr char kHex[] = "0123456789ABCDEF";
    for (const char ch : full) {
      const auto c = static_cast<unsigned char>(ch);
      if (std::isalnum(c) || std::string_view("!#$&+-.^_`|~").find(ch) != std::string_view::npos) {
        header.push_back(ch);
      } else {
        header.push_back('%');
        header.push_back(kHex[c >> 4]);
        header.push_back(kHex[c & 15]);
      }
    }
  }
  return header;
}

std::string extension_for(std::string_view content_type) {
  const std::string type = lower(trim(content_type.substr(0, content_type.find(';'))));
  if (type == "model/stl") return ".stl";
  if (type == "application/zip") return ".zip";
  if (type == "model/3mf") return ".3mf";
  if (type == "application/json") return ".json";
  if (type == "image/svg+xml") return ".svg";
  return ".bin";
}

}  // namespace stlrefine::server
