// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// Expat with the 3MF reader's guards (threemf_xml.h). Handlers run inside expat's C frames:
// an exception must not unwind through them, so a handler's throw is caught, the parser is
// stopped, and feed() rethrows once expat has returned.

#include "core/io/threemf_xml.h"

#include <expat.h>

#include <exception>

#include "core/io/reader_util.h"

namespace stlrefine::io_detail {

namespace {
// Separates an element's namespace URI from its local name (no URI holds a line break).
constexpr char kNsSeparator = '\n';

std::pair<std::string_view, std::string_view> split_name(const char* name) {
  const std::string_view s(name);
  const std::size_t at = s.find(kNsSeparator);
  if (at == std::string_view::npos) return {std::string_view(), s};
  return {s.substr(0, at), s.substr(at + 1)};
}
}  // namespace

const char* XmlAttributes::find(std::string_view name) const {
  for (const char** p = pairs_; p && *p; p += 2)
    if (name == *p) return p[1];
  return nullptr;
}

struct HardenedXml::Impl {
  HardenedXml* owner = nullptr;
  XmlHandler* handler = nullptr;
  XML_Parser parser = nullptr;
  std::exception_ptr failure;
  int depth = 0;
  std::uint64_t fed = 0;         // bytes handed to expat so far
  std::uint64_t last_event = 0;  // `fed` when expat last reported anything

  // Runs a handler body; stops the parser on the first throw.
  template <class F>
  void guarded(F&& f) {
    if (failure) return;  // expat may still call back after a stop
    last_event = fed;
    try {
      f();
    } catch (...) {
      failure = std::current_exception();
      XML_StopParser(parser, XML_FALSE);
    }
  }

  static void on_start(void* self, const XML_Char* name, const XML_Char** attrs) {
    auto* impl = static_cast<Impl*>(self);
    impl->guarded([&] {
      if (++impl->depth > kMaxXmlDepth)
        throw impl->owner->error("elements nested more than " + std::to_string(kMaxXmlDepth) +
                                 " deep");
      const auto [ns, local] = split_name(name);
      impl->handler->start(ns, local, XmlAttributes(attrs));
    });
  }
  static void on_end(void* self, const XML_Char* name) {
    auto* impl = static_cast<Impl*>(self);
    impl->guarded([&] {
      --impl->depth;
      const auto [ns, local] = split_name(name);
      impl->handler->end(ns, local);
    });
  }
  // Text, comments and processing instructions are ignored; they only mark progress.
  static void on_text(void* self, const XML_Char*, int) {
    auto* impl = static_cast<Impl*>(self);
    impl->last_event = impl->fed;
  }
  static void on_comment(void* self, const XML_Char*) {
    auto* impl = static_cast<Impl*>(self);
    impl->last_event = impl->fed;
  }
  static void on_instruction(void* self, const XML_Char*, const XML_Char*) {
    auto* impl = static_cast<Impl*>(self);
    impl->last_event = impl->fed;
  }
  static void on_doctype(void* self, const XML_Char*, const XML_Char*, const XML_Char*, int) {
    auto* impl = static_cast<Impl*>(self);
    impl->guarded([&] {
      throw impl->owner->error(
          "declares a DOCTYPE: 3MF has no DTD, and no entity is expanded here");
    });
  }
};

HardenedXml::HardenedXml(XmlHandler& handler, std::string part)
    : impl_(std::make_unique<Impl>()), part_(std::move(part)) {
  impl_->owner = this;
  impl_->handler = &handler;
  impl_->parser = XML_ParserCreateNS(nullptr, kNsSeparator);
  if (!impl_->parser) throw Error(ErrorCode::Internal, "internal", "expat: out of memory");
  XML_SetUserData(impl_->parser, impl_.get());
  XML_SetElementHandler(impl_->parser, Impl::on_start, Impl::on_end);
  XML_SetCharacterDataHandler(impl_->parser, Impl::on_text);
  XML_SetCommentHandler(impl_->parser, Impl::on_comment);
  XML_SetProcessingInstructionHandler(impl_->parser, Impl::on_instruction);
  XML_SetStartDoctypeDeclHandler(impl_->parser, Impl::on_doctype);
  XML_SetParamEntityParsing(impl_->parser, XML_PARAM_ENTITY_PARSING_NEVER);
}

HardenedXml::~HardenedXml() {
  XML_ParserFree(impl_->parser);
}

std::uint64_t HardenedXml::line() const {
  return XML_GetCurrentLineNumber(impl_->parser);
}

Error HardenedXml::error(const std::string& message, const char* reason) const {
  std::string text = part_;
  text.append(" line ").append(std::to_string(line())).append(": ").append(message);
  return malformed(reason, text).at_byte(0);
}

void HardenedXml::feed(const char* data, std::size_t size, bool last) {
  // Hand expat at most 1 MiB at a time so that the stretch check below sees progress.
  constexpr std::size_t kStep = std::size_t{1} << 20;
  do {
    const std::size_t n = size < kStep ? size : kStep;
    impl_->fed += n;
    const bool final = last && n == size;
    const XML_Status status = XML_Parse(impl_->parser, data, static_cast<int>(n), final);
    if (impl_->failure) std::rethrow_exception(impl_->failure);
    if (status != XML_STATUS_OK)
      throw error(std::string("not well-formed XML: ") +
                  XML_ErrorString(XML_GetErrorCode(impl_->parser)));
    if (impl_->fed - impl_->last_event > kMaxXmlStretch)
      throw error("more than " + std::to_string(kMaxXmlStretch) +
                      " bytes without an XML element (one tag, comment or text this long)",
                  "too_large");
    data += n;
    size -= n;
  } while (size > 0);
}

}  // namespace stlrefine::io_detail
