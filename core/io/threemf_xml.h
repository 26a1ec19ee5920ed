// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// A hardened streaming XML parser for the parts of a 3MF package (internal to core/io):
// expat, fed in chunks as the part inflates, so that the XML is never held whole. Hostile
// XML is refused as Error(MalformedStl, "not_3mf" / "too_large") naming the part and line:
// any DOCTYPE (3MF has no DTD: no entity can expand), nesting deeper than kMaxXmlDepth, and
// more than kMaxXmlStretch bytes without an XML event (expat buffers a whole tag, comment
// or attribute in memory: this bounds that buffer).

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "core/error.h"

namespace stlrefine::io_detail {

inline constexpr int kMaxXmlDepth = 64;
// expat (2.5) rescans an unfinished token on every feed: a long one costs time quadratic
// in its length, so the cap is small; 3MF's tokens are tags of a few numbers.
inline constexpr std::uint64_t kMaxXmlStretch = std::uint64_t{1} << 20;

//! An element's attributes as expat gives them: name, value, ..., nullptr.
class XmlAttributes {
 public:
  explicit XmlAttributes(const char** pairs) : pairs_(pairs) {}
  //! The value of the attribute `name` (no namespace, or "namespace\nlocal"); nullptr if absent.
  const char* find(std::string_view name) const;

 private:
  const char** pairs_;
};

//! What a part's parser is told; a handler may throw (the parser stops and rethrows).
class XmlHandler {
 public:
  virtual ~XmlHandler() = default;
  //! `ns` is the element's namespace URI ("" when it has none).
  virtual void start(std::string_view ns, std::string_view name, const XmlAttributes& attrs) = 0;
  virtual void end(std::string_view ns, std::string_view name) = 0;
};

class HardenedXml {
 public:
  //! `part` names the package part in messages ("3D/3dmodel.model").
  HardenedXml(XmlHandler& handler, std::string part);
  ~HardenedXml();
  HardenedXml(const HardenedXml&) = delete;
  HardenedXml& operator=(const HardenedXml&) = delete;

  //! Parses the next bytes of the part; `last` on the final call (which may be empty).
  void feed(const char* data, std::size_t size, bool last);
  //! The line expat is on (for the handler's own messages).
  std::uint64_t line() const;
  const std::string& part() const { return part_; }
  //! "not_3mf" with "<part> line <n>: <message>", located at byte 0 of the upload (a
  //! compressed part has no useful offset in it).
  Error error(const std::string& message, const char* reason = "not_3mf") const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::string part_;
};

}  // namespace stlrefine::io_detail
