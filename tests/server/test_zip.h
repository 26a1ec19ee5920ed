// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <map>
#include <string>

namespace stlrefine::test {

//! The entries of a zip held in memory (name -> bytes), read with libzip; a test failure
//! (and an empty map) when it is not a zip.
std::map<std::string, std::string> unzip(const std::string& bytes);

}  // namespace stlrefine::test
