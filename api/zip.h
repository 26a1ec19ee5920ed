// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// A zip archive built in memory with libzip: the one-response answer of a refine + slice
// request (refined STL, contours, report). Zip because every desktop opens it and curl
// saves it as one file; ZIP64 is used by libzip when an entry passes 4 GiB.

#include <string>
#include <string_view>
#include <vector>

namespace stlrefine::api {

struct ZipEntry {
  std::string name;       //!< path inside the archive
  std::string_view data;  //!< must outlive make_zip
  bool deflate = true;    //!< deflate (level 1) or store as is
};

//! The archive's bytes. \throw Error(Internal) when libzip fails.
std::string make_zip(const std::vector<ZipEntry>& entries);

}  // namespace stlrefine::api
