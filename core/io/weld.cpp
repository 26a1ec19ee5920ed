// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/io/huge_pages.h"
#include "core/io/stl.h"

namespace stlrefine {
namespace {

constexpr std::uint32_t kEmpty = std::numeric_limits<std::uint32_t>::max();

std::size_t next_pow2(std::size_t n) {
  return std::bit_ceil(std::max<std::size_t>(n, 16));
}

std::uint64_t mix64(std::uint64_t x) {
  // murmur3 / splitmix finaliser: every input bit reaches every output bit.
  x ^= x >> 33;
  x *= 0xff51afd7ed558ccdull;
  x ^= x >> 33;
  x *= 0xc4ceb9fe1a85ec53ull;
  x ^= x >> 33;
  return x;
}

//! Open-addressing map from a bit-exact float position (3 x uint32, -0.0 folded into
//! +0.0) to a vertex index. A slot holds the whole 12-byte key and the index (16 bytes), so
//! a probe touches one cache line and never the position array. Linear probing, power-of-two
//! capacity, at most half full.
class ExactVertexTable {
 public:
  explicit ExactVertexTable(std::size_t expected_vertices) {
    allocate(slots_, next_pow2(2 * expected_vertices));
    mask_ = slots_.size() - 1;
  }

  static std::uint64_t hash(const std::uint32_t key[3]) {
    const std::uint64_t lo = (std::uint64_t{key[1]} << 32) | key[0];
    return mix64(lo ^ (std::uint64_t{key[2]} * 0x9e3779b97f4a7c15ull));
  }

  //! Starts loading the slot where a key with this hash begins its probe.
  void prefetch(std::uint64_t h) const { __builtin_prefetch(&slots_[h & mask_]); }

  //! The index stored for `key` (whose hash is h), or `fresh` after inserting it.
  std::uint32_t find_or_insert(const std::uint32_t key[3], std::uint64_t h, std::uint32_t fresh) {
    if (2 * (size_ + 1) > slots_.size()) grow();
    std::size_t i = h & mask_;
    for (;;) {
      Slot& s = slots_[i];
      if (s.index == kEmpty) {
        std::memcpy(s.key, key, sizeof s.key);
        s.index = fresh;
        ++size_;
        return fresh;
      }
      if (s.key[0] == key[0] && s.key[1] == key[1] && s.key[2] == key[2]) return s.index;
      i = (i + 1) & mask_;
    }
  }

 private:
  struct Slot {
    std::uint32_t key[3];
    std::uint32_t index = kEmpty;
  };

  static void allocate(std::vector<Slot>& slots, std::size_t n) {
    io_detail::reserve_huge(slots, n);
    slots.resize(n);
  }

  void grow() {
    std::vector<Slot> old;
    allocate(old, 2 * slots_.size());
    old.swap(slots_);
    mask_ = slots_.size() - 1;
    for (const Slot& s : old) {
      if (s.index == kEmpty) continue;
      std::size_t i = hash(s.key) & mask_;
      while (slots_[i].index != kEmpty) i = (i + 1) & mask_;
      slots_[i] = s;
    }
  }

  std::vector<Slot> slots_;
  std::size_t mask_ = 0;
  std::size_t size_ = 0;
};

IndexedSoup weld_exact(const TriangleSoup& soup) {
  const std::size_t corners = soup.coords.size() / 3;
  IndexedSoup out;
  io_detail::reserve_huge(out.triangles, corners / 3);
  out.triangles.resize(corners / 3);
  // Closed meshes have about half as many vertices as triangles; soups up to 3 times as
  // many. Start at the closed-mesh size; the table and the vector grow when needed.
  io_detail::reserve_huge(out.positions, corners / 6 + 16);
  ExactVertexTable table(corners / 6 + 16);

  // The table is far larger than the caches, so each lookup is a memory access. Hashing
  // kAhead corners in advance and prefetching their slots keeps several of those accesses
  // in flight at once; the corners are still inserted strictly in order.
  constexpr std::size_t kAhead = 16;
  struct Pending {
    std::uint32_t key[3];
    std::uint64_t hash;
  };
  Pending ring[kAhead];
  const auto stage = [&](std::size_t i) {
    Pending& p = ring[i % kAhead];
    std::memcpy(p.key, &soup.coords[3 * i], sizeof p.key);
    for (std::uint32_t& k : p.key) k = (k == 0x80000000u) ? 0u : k;  // -0.0 == +0.0
    p.hash = ExactVertexTable::hash(p.key);
    table.prefetch(p.hash);
  };
  for (std::size_t i = 0; i < std::min(kAhead, corners); ++i) stage(i);
  for (std::size_t i = 0; i < corners; ++i) {
    const Pending p = ring[i % kAhead];
    if (i + kAhead < corners) stage(i + kAhead);
    const auto fresh = static_cast<std::uint32_t>(out.positions.size());
    const std::uint32_t v = table.find_or_insert(p.key, p.hash, fresh);
    if (v == fresh) {
      out.positions.emplace_back(std::bit_cast<float>(p.key[0]), std::bit_cast<float>(p.key[1]),
                                 std::bit_cast<float>(p.key[2]));
    }
    out.triangles[i / 3][i % 3] = v;
  }
  return out;
}

//! Uniform grid over space with cells at least 2.5 tolerance wide. Every point within
//! tolerance of p then lies in the 2x2x2 block of cells on p's side of its own cell (per
//! axis: p's cell and the neighbour p is nearer to), with a margin of 0.1 cell, far above
//! the rounding of p / cell. Each cell keeps a linked list of its vertices (head in an
//! open-addressing table, links in `next_`).
class GridWelder {
 public:
  static constexpr double kCellsPerTolerance = 2.5;

  GridWelder(double cell, std::size_t expected_vertices)
      : inv_cell_(1.0 / cell), slots_(next_pow2(2 * expected_vertices)), mask_(slots_.size() - 1) {}

  std::uint32_t weld(const Vec3& p, double tolerance, std::vector<Vec3>& positions) {
    const double q[3] = {p.x * inv_cell_, p.y * inv_cell_, p.z * inv_cell_};
    const Cell c = {static_cast<std::int64_t>(std::floor(q[0])),
                    static_cast<std::int64_t>(std::floor(q[1])),
                    static_cast<std::int64_t>(std::floor(q[2]))};
    // Per axis, the neighbour on p's side: -1 in the lower half of the cell, else +1.
    const std::int64_t side[3] = {q[0] - static_cast<double>(c.x) < 0.5 ? -1 : 1,
                                  q[1] - static_cast<double>(c.y) < 0.5 ? -1 : 1,
                                  q[2] - static_cast<double>(c.z) < 0.5 ? -1 : 1};
    const double limit2 = tolerance * tolerance;
    std::uint32_t best = kEmpty;
    double best_d2 = std::numeric_limits<double>::infinity();
    for (const std::int64_t dx : {std::int64_t{0}, side[0]}) {
      for (const std::int64_t dy : {std::int64_t{0}, side[1]}) {
        for (const std::int64_t dz : {std::int64_t{0}, side[2]}) {
          const Slot* s = find({c.x + dx, c.y + dy, c.z + dz});
          if (s == nullptr) continue;
          for (std::uint32_t v = s->head; v != kEmpty; v = next_[v]) {
            const Vec3 d = positions[v] - p;
            const double d2 = dot(d, d);
            if (d2 <= limit2 && (d2 < best_d2 || (d2 == best_d2 && v < best))) {
              best = v;
              best_d2 = d2;
            }
          }
        }
      }
    }
    if (best != kEmpty) return best;
    const auto v = static_cast<std::uint32_t>(positions.size());
    positions.push_back(p);
    Slot& s = find_or_insert(c);
    next_.push_back(s.head);
    s.head = v;
    return v;
  }

 private:
  struct Cell {
    std::int64_t x, y, z;
    bool operator==(const Cell&) const = default;
  };
  struct Slot {
    Cell cell{};
    std::uint32_t head = kEmpty;
    bool used = false;
  };

  static std::size_t hash(const Cell& c) {
    return static_cast<std::size_t>(mix64(static_cast<std::uint64_t>(c.x) * 0x9e3779b97f4a7c15ull ^
                                          static_cast<std::uint64_t>(c.y) * 0xc2b2ae3d27d4eb4full ^
                                          static_cast<std::uint64_t>(c.z)));
  }

  const Slot* find(const Cell& c) const {
    for (std::size_t i = hash(c) & mask_;; i = (i + 1) & mask_) {
      const Slot& s = slots_[i];
      if (!s.used) return nullptr;
      if (s.cell == c) return &s;
    }
  }

  Slot& find_or_insert(const Cell& c) {
    if (2 * (size_ + 1) > slots_.size()) grow();
    std::size_t i = hash(c) & mask_;
    while (slots_[i].used && !(slots_[i].cell == c)) i = (i + 1) & mask_;
    Slot& s = slots_[i];
    if (!s.used) {
      s.used = true;
      s.cell = c;
      ++size_;
    }
    return s;
  }

  void grow() {
    std::vector<Slot> old(2 * slots_.size());
    old.swap(slots_);
    mask_ = slots_.size() - 1;
    for (const Slot& s : old) {
      if (!s.used) continue;
      std::size_t i = hash(s.cell) & mask_;
      while (slots_[i].used) i = (i + 1) & mask_;
      slots_[i] = s;
    }
  }

  double inv_cell_;
  std::vector<Slot> slots_;
  std::size_t mask_;
  std::size_t size_ = 0;
  std::vector<std::uint32_t> next_;  // next vertex in the same cell
};

IndexedSoup weld_tolerance(const TriangleSoup& soup, double tolerance) {
  double max_abs = 0;
  for (const float f : soup.coords) {
    if (!std::isfinite(f)) {
      throw Error(ErrorCode::InvalidParameter, "non_finite",
                  "tolerance welding needs finite coordinates")
          .with_field("soup");
    }
    max_abs = std::max(max_abs, std::fabs(static_cast<double>(f)));
  }
  // Cells are never narrower than 2.5 tolerance (correctness) nor so narrow that cell
  // indices leave int64 (a tolerance far below float spacing just behaves like exact
  // welding). The 1e-30 floor keeps 1 / cell finite for denormal tolerances.
  const double cell =
      std::max({GridWelder::kCellsPerTolerance * tolerance, max_abs * 0x1p-40, 1e-30});
  const std::size_t corners = soup.coords.size() / 3;
  IndexedSoup out;
  out.triangles.resize(corners / 3);
  out.positions.reserve(corners / 6 + 16);
  GridWelder grid(cell, corners / 6 + 16);
  for (std::size_t i = 0; i < corners; ++i) {
    // "+ 0.0" turns -0.0 into +0.0, as exact welding does.
    const Vec3 p(soup.coords[3 * i] + 0.0, soup.coords[3 * i + 1] + 0.0,
                 soup.coords[3 * i + 2] + 0.0);
    out.triangles[i / 3][i % 3] = grid.weld(p, tolerance, out.positions);
  }
  return out;
}

}  // namespace

IndexedSoup weld(const TriangleSoup& soup, double tolerance) {
  if (!(tolerance >= 0) || !std::isfinite(tolerance)) {
    throw Error(ErrorCode::InvalidParameter, "out_of_range",
                "weld tolerance = " + std::to_string(tolerance) +
                    " must be finite and >= 0 (0 = exact welding)")
        .with_field("tolerance");
  }
  if (soup.coords.size() % 9 != 0) {
    throw Error(
        ErrorCode::InvalidParameter, "bad_soup",
        "a triangle soup holds 9 floats per triangle, not " + std::to_string(soup.coords.size()))
        .with_field("soup");
  }
  if (soup.coords.size() / 3 >= kEmpty) {
    throw Error(ErrorCode::BudgetExceeded, "too_many_triangles",
                "more corners than 32-bit vertex indices can hold")
        .with_field("soup");
  }
  return tolerance == 0 ? weld_exact(soup) : weld_tolerance(soup, tolerance);
}

}  // namespace stlrefine
