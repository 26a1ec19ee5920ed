// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// What a request with a body uploads: the file's bytes and its name. A raw body is the
// file (its name from a `Content-Disposition: ...; filename=` request header); a
// `multipart/form-data` body (curl -F file=@part.stl) holds it in its one part named
// `file`. Either way the body was framed by Content-Length and read whole under the same
// limits, so a multipart body is parsed here from memory: a boundary that never closes is
// a 400, never a wait. And the names of the downloads made from it: `part_refined.stl`,
// sanitised for a Content-Disposition header.

#include <optional>
#include <string>
#include <string_view>

#include "api/problem.h"
#include "server/http.h"

namespace stlrefine::server {

struct Upload {
  std::string_view bytes;  //!< the file (a view into the request's body)
  //! The client's file name, sanitised (upload_name()); empty when none was given.
  std::string name;
};

//! The multipart boundary of a `multipart/form-data` Content-Type, or nullopt when the
//! type is not multipart/form-data; an empty string when it is but has no usable boundary
//! (RFC 2046: 1..70 characters).
std::optional<std::string> multipart_boundary(std::string_view content_type);

//! The file a request uploads, and its name: the part's filename, a raw body's
//! Content-Disposition filename, else the query's `filename=`. 400 (bad-request, `field`
//! names the part, header or parameter) for a repeated `filename`, for a
//! multipart body without a `file` part, with a second one, with another field (parameters
//! are given in the query string), with malformed part headers or without its closing
//! boundary.
std::optional<api::Problem> read_upload(const HttpRequest& req, Upload& out);

//! A client's file name as it may be kept: the last path component, without control
//! characters and invalid UTF-8, at most 240 bytes (cut at a character boundary), trimmed
//! of spaces and dots; empty when nothing is left.
std::string upload_name(std::string_view raw);

//! The name a download is based on: the upload's name without its extension ("part" when
//! there is none).
std::string download_stem(std::string_view upload_name);

//! `attachment; filename="STEM_SUFFIX"` (ASCII, every byte that could break the header or a
//! path made `_`), plus RFC 6266 `filename*=UTF-8''...` when the name is not plain ASCII.
std::string content_disposition(std::string_view stem, std::string_view suffix);

//! The extension of a download of this media type (".stl", ".zip", ".3mf", ".svg", ".cli",
//! ".json"; ".bin" for anything else).
std::string extension_for(std::string_view content_type);

}  // namespace stlrefine::server
