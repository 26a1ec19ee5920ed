// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <cstdint>
#include <functional>
#include <limits>

namespace stlrefine {

//! A typed 32-bit index. Distinct tags make it a compile error to pass a face where a
//! vertex is expected; `invalid()` is the explicit "none" value (no -1 on int).
template <class Tag>
struct Handle {
  static constexpr std::uint32_t kInvalid = std::numeric_limits<std::uint32_t>::max();
  std::uint32_t idx = kInvalid;

  constexpr Handle() = default;
  constexpr explicit Handle(std::uint32_t i) : idx(i) {}
  static constexpr Handle invalid() { return Handle(); }
  constexpr bool valid() const { return idx != kInvalid; }
  constexpr friend bool operator==(Handle a, Handle b) { return a.idx == b.idx; }
  constexpr friend bool operator!=(Handle a, Handle b) { return a.idx != b.idx; }
  constexpr friend bool operator<(Handle a, Handle b) { return a.idx < b.idx; }
};

using VertexId = Handle<struct VertexTag>;
using HalfedgeId = Handle<struct HalfedgeTag>;
using EdgeId = Handle<struct EdgeTag>;
using FaceId = Handle<struct FaceTag>;

}  // namespace stlrefine

template <class Tag>
struct std::hash<stlrefine::Handle<Tag>> {
  std::size_t operator()(stlrefine::Handle<Tag> h) const noexcept { return h.idx; }
};
