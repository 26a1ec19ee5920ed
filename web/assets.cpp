// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "web/assets.h"

namespace stlrefine::web {

const Asset* find_asset(std::string_view name) {
  for (const Asset& a : assets())
    if (a.name == name) return &a;
  return nullptr;
}

}  // namespace stlrefine::web
