// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/adaptive_sqrt3.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <deque>
#include <limits>
#include <memory>
#include <numbers>
#include <string>
#include <utility>

#include "core/error.h"
#include "core/geometry/point_triangle.h"
#include "core/parallel.h"
#include "core/refine.h"

namespace stlrefine {

namespace {

constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
constexpr std::uint32_t kUnknown = kNone - 1;  // a neighbour not looked up yet

// A half-edge of the hierarchy: edge k (v[k] -> v[k+1]) of triangle t.
struct He {
  std::uint32_t t = kNone;
  std::uint8_t k = 0;
  bool valid() const { return t != kNone; }
  friend bool operator==(He a, He b) { return a.t == b.t && a.k == b.k; }
};

He next(He h) {
  return {h.t, static_cast<std::uint8_t>(h.k == 2 ? 0 : h.k + 1)};
}
He prev(He h) {
  return {h.t, static_cast<std::uint8_t>(h.k == 0 ? 2 : h.k - 1)};
}

enum TriFlag : std::uint8_t {
  kRefined = 1,        // split (1-to-3, or cut at a sharp edge's trisection points)
  kFlip = 2,           // made by a flip: exists once the triangles on both sides are refined
  kQueued = 4,         // in the driver's queue
  kPiecesChecked = 8,  // refined, and its pieces (edges not flipped yet) were measured
};

// A triangle of the uniform hierarchy at its level. Corner order, neighbours and children
// follow sqrt3_refine's layout: child k is the fine face of half-edge k.
struct Tri {
  std::array<std::uint32_t, 3> v{};
  std::array<std::uint32_t, 3> nbr{kUnknown, kUnknown, kUnknown};  // kNone: boundary
  std::array<std::uint32_t, 3> child{kNone, kNone, kNone};
  std::uint32_t owner = kNone;   // the coarser triangle whose half-edge made it
  std::uint32_t point = kNone;   // face point, or the trisection point nearest from(s)
  std::uint32_t point2 = kNone;  // the trisection point nearest to(s)
  std::array<std::uint8_t, 3> nbr_edge{};
  std::uint8_t owner_edge = 0;
  std::uint8_t level = 0;
  std::uint8_t sharp = 0;  // bit k: edge k is sharp
  std::uint8_t canon = 0;  // bit k: sharp edge k is its edge's canonical half in sqrt3_refine
  std::uint8_t flags = 0;
};

enum class Origin : std::uint8_t { Input, FacePoint, NearFrom, NearTo };

struct Vert {
  std::uint32_t tri = kNone;  // the triangle whose face point / trisection point it is
  std::uint32_t slot = 0;     // first of its positions in the pool
  He home;                    // a half-edge from it at its own level (invalid: not known yet)
  Origin origin = Origin::Input;
  std::uint8_t level = 0;
};

// The criterion measures the surface two levels finer; the levels after those add a tail.
// Per double step the deviation from the flat shrinks at least by the largest eigenvalue
// of the double step's subdivision matrix below the affine 1, 1/3, 1/3: 0.180019 at valence
// 6, 1/9 at the others, 11/81 on curves (Labsik-Greiner; spec 3.2-3.4, bench/RESULTS.md
// "## sqrt3"; sqrt3-unified with alpha 1: 0.160 at valence 6). The whole deviation is then
// at most 1 / (1 - 0.180019) = 1.22 times the measured one in the asymptotic regime; on
// coarse irregular meshes it was measured, not proven (tests: bunny_low, sphere_fn16).
constexpr double kTail = 1.0 / (1.0 - 0.180019);

Error internal(const std::string& what) {
  return Error(ErrorCode::Internal, "adaptive_sqrt3", "adaptive sqrt3: " + what);
}

// The hierarchy's arrays: they grow a chunk at a time and never move. A vector holds its
// old and new buffers while it doubles and keeps up to twice what it uses; these hold what
// they use rounded up to one chunk, and memory admission reserves them a chunk at a time.
// References to elements stay valid while it grows.
template <class T>
class Chunked {
 public:
  static constexpr int kShift = 14;
  static constexpr std::size_t kChunk = std::size_t{1} << kShift;
  static constexpr std::uint64_t kChunkBytes = sizeof(T) * kChunk;

  T& operator[](std::size_t i) { return chunks_[i >> kShift][i & (kChunk - 1)]; }
  const T& operator[](std::size_t i) const { return chunks_[i >> kShift][i & (kChunk - 1)]; }
  std::size_t size() const { return size_; }
  std::size_t capacity() const { return chunks_.size() * kChunk; }
  //! Bytes of the chunks (and their table) to add before the size can be n.
  std::uint64_t growth_bytes(std::size_t n) const {
    const std::size_t chunks = (n + kChunk - 1) >> kShift;
    return chunks > chunks_.size() ? (chunks - chunks_.size()) * (kChunkBytes + sizeof(void*)) : 0;
  }
  //! Grows to n elements, the new ones set to `value`.
  void grow(std::size_t n, const T& value = T()) {
    while (chunks_.size() * kChunk < n) chunks_.push_back(std::make_unique<T[]>(kChunk));
    for (std::size_t i = size_; i < n; ++i) (*this)[i] = value;
    size_ = n;
  }
  void push_back(const T& value) { grow(size_ + 1, value); }
  //! Drops the elements from n on, and the chunks they alone used.
  void truncate(std::size_t n) {
    size_ = std::min(size_, n);
    chunks_.resize((size_ + kChunk - 1) >> kShift);
  }
  std::uint64_t bytes() const {
    return chunks_.size() * kChunkBytes + chunks_.capacity() * sizeof(void*);
  }

 private:
  std::vector<std::unique_ptr<T[]>> chunks_;
  std::size_t size_ = 0;
};

// The heap a stencil patch takes per face (its small mesh, features and index arrays,
// about 130 B) with room for allocator headers, and per patch.
constexpr std::uint64_t kPatchFaceBytes = 256;
constexpr std::uint64_t kPatchBytes = 4096;

}  // namespace

class AdaptiveSqrt3::Hierarchy {
 public:
  Hierarchy(const Level& coarse, const Sqrt3Stencil& stencil, const Sqrt3AdaptiveCriteria& c,
            std::function<void(std::uint64_t)> reserve)
      : stencil_(stencil),
        criteria_(c),
        interpolating_(stencil.interpolating()),
        top_level_(c.max_level + 2),
        input_vertices_(static_cast<std::uint32_t>(coarse.mesh.num_vertices())),
        input_faces_(coarse.mesh.num_faces()),
        reserve_(std::move(reserve)) {
    const Mesh& m = coarse.mesh;
    // Patches: a triangle and the fans round its corners, at most one per level alive at
    // once (positions recurse to coarser levels). Old vertices keep their valence; new
    // ones have at most 6, or a few more next to a crease.
    int valence = 12;
    for (std::uint32_t v = 0; v < input_vertices_; ++v)
      if (!m.is_isolated(VertexId(v))) valence = std::max(valence, m.valence(VertexId(v)));
    patch_bytes_ = std::uint64_t(top_level_ + 1) *
                   (kPatchBytes + kPatchFaceBytes * (1 + 3 * std::uint64_t(valence)));
    need(held_bytes() + big_vector_bytes<double>(input_vertices_));  // the initial alpha
    const BigVector<double> alpha = stencil.initial_alpha(coarse);
    has_alpha_ = !alpha.empty();
    for (std::uint32_t v = 0; v < input_vertices_; ++v) {
      const std::uint32_t id = new_vertex(Origin::Input, kNone, 0);
      const HalfedgeId h = m.halfedge(VertexId(v));
      if (h.valid()) verts_[id].home = {h.idx / 3, static_cast<std::uint8_t>(h.idx % 3)};
      set_position(id, 0, m.position(VertexId(v)));
      if (has_alpha_) alpha_[id] = alpha[v];
    }
    for (std::uint32_t f = 0; f < m.num_faces(); ++f) {
      Tri t;
      for (std::uint8_t k = 0; k < 3; ++k) {
        const HalfedgeId h(3 * f + k);
        t.v[k] = m.from(h).idx;
        const HalfedgeId tw = m.twin(h);
        t.nbr[k] = tw.valid() ? tw.idx / 3 : kNone;
        t.nbr_edge[k] = tw.valid() ? static_cast<std::uint8_t>(tw.idx % 3) : 0;
        if (coarse.features.is_sharp(m.edge(h))) t.sharp |= 1 << k;
        if (m.halfedge(m.edge(h)) == h) t.canon |= 1 << k;
      }
      add_tri(t);
    }
  }

  void run(std::uint64_t max_faces, const std::atomic<bool>* cancel,
           const std::function<void(int)>& level_started);
  Level result(std::vector<std::uint8_t>* face_level);
  const Sqrt3AdaptiveStats& stats() const { return stats_; }

 private:
  // --- the hierarchy's connectivity (mirrors sqrt3_refine's Sqrt3Layout)

  static bool trisects(int level) { return level % 2 == 1; }
  int level(std::uint32_t t) const { return tris_[t].level; }
  bool flag(std::uint32_t t, TriFlag f) const { return (tris_[t].flags & f) != 0; }
  bool refined(std::uint32_t t) const { return flag(t, kRefined); }
  std::uint32_t from(He h) const { return tris_[h.t].v[h.k]; }
  std::uint32_t to(He h) const { return tris_[h.t].v[next(h).k]; }
  std::uint32_t opposite(He h) const { return tris_[h.t].v[prev(h).k]; }
  bool sharp(He h) const { return (tris_[h.t].sharp >> h.k) & 1; }
  bool canonical(He h) const { return (tris_[h.t].canon >> h.k) & 1; }

  // In a trisecting level, the face's one sharp half-edge (invalid: none).
  He sharp_of(std::uint32_t t) const {
    He s;
    for (std::uint8_t k = 0; k < 3; ++k) {
      if (!((tris_[t].sharp >> k) & 1)) continue;
      if (s.valid()) throw internal("a trisecting level has a face with two sharp edges");
      s = {t, k};
    }
    return s;
  }
  // Both sides refined: an old edge is flipped; a sharp one is kept.
  bool makes_flip_child(He h) {
    if (trisects(level(h.t))) return !(h == sharp_of(h.t));
    return !sharp(h) && twin(h).valid();
  }

  He twin(He h);
  He derive_twin(He h);
  He fine(He h, std::uint8_t k) { return {child(h), k}; }
  std::uint32_t child(He h);
  std::uint32_t face_point(std::uint32_t t);
  std::pair<std::uint32_t, std::uint32_t> trisection(He s);
  std::uint32_t apex(He h);

  bool exists(std::uint32_t t) {
    if (level(t) == 0) return true;
    const std::uint32_t p = tris_[t].owner;
    if (!refined(p)) return false;
    return !flag(t, kFlip) || refined(twin({p, tris_[t].owner_edge}).t);
  }

  // --- vertices and positions

  std::uint32_t new_vertex(Origin origin, std::uint32_t tri, int level) {
    const auto id = static_cast<std::uint32_t>(verts_.size());
    Vert v;
    v.tri = tri;
    v.origin = origin;
    v.level = static_cast<std::uint8_t>(level);
    v.slot = static_cast<std::uint32_t>(pool_.size());
    // Interpolating stencils never move a vertex: one position. Others: one per level.
    const int slots = interpolating_ ? 1 : std::max(1, top_level_ - level + 1);
    const std::uint64_t growth = pool_.growth_bytes(pool_.size() + slots) +
                                 known_.growth_bytes(known_.size() + slots) +
                                 verts_.growth_bytes(verts_.size() + 1) +
                                 (has_alpha_ ? alpha_.growth_bytes(alpha_.size() + 1) : 0);
    if (growth) need(held_bytes() + growth);
    pool_.grow(pool_.size() + slots);
    known_.grow(known_.size() + slots, 0);
    verts_.push_back(v);
    if (has_alpha_) alpha_.push_back(1.0);
    return id;
  }
  std::uint32_t add_tri(const Tri& t) {
    if (const std::uint64_t growth = tris_.growth_bytes(tris_.size() + 1))
      need(held_bytes() + growth);
    tris_.push_back(t);
    return static_cast<std::uint32_t>(tris_.size() - 1);
  }

  // --- memory (see AdaptiveSqrt3's comment)

  //! Everything the hierarchy holds now, and what may be alive besides at any moment.
  std::uint64_t held_bytes() const {
    // The queues hold each triangle at most once: 4 B each, their blocks and maps about 2 %
    // more, and a partly used block per queue.
    const std::uint64_t queues = 5 * std::uint64_t(tris_.capacity()) + queue_.size() * 2048;
    return tris_.bytes() + verts_.bytes() + pool_.bytes() + known_.bytes() + alpha_.bytes() +
           queues + patch_bytes_ + transient_bytes_;
  }
  void need(std::uint64_t bytes) const {
    if (reserve_) reserve_(bytes);
  }
  //! The cap count's triangles and vertices are only measured: it drops them in batches.
  struct Checkpoint {
    std::size_t tris, verts, slots;
  };
  Checkpoint checkpoint() const { return {tris_.size(), verts_.size(), pool_.size()}; }
  void rollback(const Checkpoint& c);
  std::uint32_t slot_of(std::uint32_t v, int level) const {
    const Vert& info = verts_[v];
    return info.slot + (interpolating_ ? 0 : static_cast<std::uint32_t>(level - info.level));
  }
  void set_position(std::uint32_t v, int level, const Vec3& p) {
    const std::uint32_t s = slot_of(v, level);
    pool_[s] = p;
    known_[s] = 1;
  }
  Vec3 position(std::uint32_t v, int level);
  Vec3 creation_position(std::uint32_t v);
  He home(std::uint32_t v);
  He halfedge_at(std::uint32_t v, int level);

  // --- stencil evaluation on a patch of one level

  struct Patch {
    Mesh mesh;
    Features features;
    BigVector<double> alpha;
    //! Trisecting levels: per local face, its sharp edge (Sqrt3Step::sharp_corner) from
    //! the hierarchy's flags: the patch's own features also call the edges where the
    //! patch ends sharp (they are its boundary).
    BigVector<std::uint8_t> sharp_corner;
    std::vector<std::uint32_t> vertices;  // local -> global, sorted
  };
  void gather_fan(He h, std::vector<std::uint32_t>& out);
  Patch build_patch(std::vector<std::uint32_t> tris, int level);
  Sqrt3Step step_of(const Patch& p, int level) const {
    return Sqrt3Step{p.mesh, p.features, trisects(level), p.alpha, p.sharp_corner};
  }

  // --- the driver

  bool wants_refinement(std::uint32_t t);
  void cover(std::uint32_t t, std::vector<std::uint32_t>& out);
  double height_over(const std::array<Vec3, 3>& flat, std::uint8_t sharp,
                     std::vector<std::uint32_t> fine, int l, double limit, bool folds);
  double deviation(std::uint32_t t, double limit);
  double piece_deviation(He h, double limit);
  bool refine_across_pieces_over_tolerance();
  void refine(std::uint32_t t);
  void ensure_exists(std::uint32_t t) {
    if (level(t) == 0) return;
    const He owner{tris_[t].owner, tris_[t].owner_edge};
    refine(owner.t);
    if (flag(t, kFlip)) refine(twin(owner).t);
  }
  // A DELETE'd job, a deadline or a client that hung up raises the flag passed to run()
  // or the caller's CancelScope. Checked before every triangle is examined and before every
  // split: one check is a relaxed load, far cheaper than either.
  void throw_if_cancelled() const {
    for (const std::atomic<bool>* flag : {cancel_, scope_cancel_})
      if (flag && flag->load(std::memory_order_relaxed))
        throw Error(ErrorCode::Cancelled, "cancelled", "refinement cancelled");
  }
  void enqueue(std::uint32_t t) {
    if (flag(t, kQueued) || level(t) >= criteria_.max_level) return;
    tris_[t].flags |= kQueued;
    queue_[level(t)].push_back(t);
  }

  const Sqrt3Stencil& stencil_;
  Sqrt3AdaptiveCriteria criteria_;
  bool interpolating_;
  bool has_alpha_ = false;
  int top_level_;  // the finest level any position is asked for (two past the cap)
  std::uint32_t input_vertices_;
  std::size_t input_faces_;

  Chunked<Tri> tris_;
  Chunked<Vert> verts_;
  Chunked<Vec3> pool_;
  Chunked<std::uint8_t> known_;
  Chunked<double> alpha_;

  std::array<std::deque<std::uint32_t>, 9> queue_;
  std::size_t refined_count_ = 0;
  std::uint64_t max_faces_ = 0;
  const std::atomic<bool>* cancel_ = nullptr;
  const std::atomic<bool>* scope_cancel_ = nullptr;  // the CancelScope run() was called in
  Sqrt3AdaptiveStats stats_;
  std::function<void(std::uint64_t)> reserve_;
  std::uint64_t patch_bytes_ = 0;      // the stencil patches alive at once, at most
  std::uint64_t transient_bytes_ = 0;  // a work array alive now besides the hierarchy
};

// ---------------------------------------------------------------------------------------
// Connectivity. A triangle of level l + 1 is child(h) of a level-l half-edge h; its corners
// and neighbours are sqrt3_refine's fine_face_plain / fine_face_trisecting, read here one
// triangle at a time instead of for the whole level.

He AdaptiveSqrt3::Hierarchy::twin(He h) {
  const std::uint32_t n = tris_[h.t].nbr[h.k];
  if (n == kNone) return {};
  if (n != kUnknown) return {n, tris_[h.t].nbr_edge[h.k]};
  const He r = derive_twin(h);
  if (r.valid() && (from(h) != to(r) || to(h) != from(r)))
    throw internal("neighbours at a level do not share their edge");
  tris_[h.t].nbr[h.k] = r.valid() ? r.t : kNone;
  tris_[h.t].nbr_edge[h.k] = r.k;
  if (r.valid()) {
    tris_[r.t].nbr[r.k] = h.t;
    tris_[r.t].nbr_edge[r.k] = h.k;
  }
  return r;
}

He AdaptiveSqrt3::Hierarchy::derive_twin(He h) {
  const He c{tris_[h.t].owner, tris_[h.t].owner_edge};  // the coarse half-edge that made h.t
  if (!trisects(level(c.t))) {
    const He t = twin(c);
    const bool flipped = t.valid() && !sharp(c);
    switch (h.k) {
      case 0:  // a -> apex across (flipped), or the kept edge a -> b
        if (flipped) return fine(next(t), 2);
        return t.valid() ? fine(t, 0) : He{};
      case 1:
        return flipped ? fine(t, 1) : fine(next(c), 2);
      default: {  // the spoke apex -> a, shared with the child of prev(c) or its twin's
        const He p = prev(c);
        const He tp = twin(p);
        return tp.valid() && !sharp(p) ? fine(tp, 0) : fine(p, 1);
      }
    }
  }
  const He s = sharp_of(c.t);
  if (c == s) {  // the middle child (m1, m2, apex) of a face cut at its sharp edge
    switch (h.k) {
      case 0: {
        const He t = twin(s);
        return t.valid() ? fine(t, 0) : He{};
      }
      case 1:
        return fine(twin(next(s)), 0);
      default:
        return fine(prev(s), 2);
    }
  }
  const He t = twin(c);
  switch (h.k) {
    case 0: {  // a -> apex(t): when t's face is cut, possibly the first third of its edge
      const He sg = sharp_of(t.t);
      if (!sg.valid()) return fine(next(t), 2);
      if (t == next(sg)) return fine(sg, 1);
      const He across = twin(sg);
      return across.valid() ? fine(next(across), 2) : He{};
    }
    case 1:
      return fine(t, 1);
    default: {  // apex(c) -> a: when c's face is cut, possibly the last third of its edge
      if (!s.valid()) return fine(twin(prev(c)), 0);
      if (c == next(s)) {
        const He across = twin(s);
        return across.valid() ? fine(twin(prev(across)), 0) : He{};
      }
      return fine(s, 2);
    }
  }
}

std::uint32_t AdaptiveSqrt3::Hierarchy::child(He h) {
  if (tris_[h.t].child[h.k] != kNone) return tris_[h.t].child[h.k];
  const int l = level(h.t);
  Tri c;
  c.level = static_cast<std::uint8_t>(l + 1);
  c.owner = h.t;
  c.owner_edge = h.k;
  if (!trisects(l)) {
    const He t = twin(h);
    if (t.valid() && !sharp(h)) {
      c.v = {from(h), face_point(t.t), face_point(h.t)};
      c.flags = kFlip;
    } else {  // a sharp edge is kept whole with its face point's triangle
      c.v = {from(h), to(h), face_point(h.t)};
      c.sharp = 1;
      c.canon = canonical(h) ? 1 : 0;
    }
  } else {
    const He s = sharp_of(h.t);
    if (h == s) {
      const auto [m1, m2] = trisection(s);
      c.v = {m1, m2, opposite(s)};
      c.sharp = 1;
      c.canon = canonical(s) ? 1 : 0;
    } else {
      const He t = twin(h);
      c.v = {from(h), apex(t), apex(h)};
      c.flags = kFlip;
      // a -> m1 is the first third of the sharp edge of t's face; its canonical half is on
      // the other side of a crease (the last third there), on this side at a boundary.
      const He sg = sharp_of(t.t);
      if (sg.valid() && t == prev(sg)) {
        c.sharp |= 1;
        if (!twin(sg).valid()) c.canon |= 1;
      }
      // m2 -> a is the last third of this face's sharp edge; this side is canonical.
      if (s.valid() && h == next(s)) {
        c.sharp |= 4;
        c.canon |= 4;
      }
    }
  }
  if (tris_[h.t].child[h.k] != kNone) throw internal("a child was made twice");
  const std::uint32_t id = add_tri(c);
  tris_[h.t].child[h.k] = id;
  return id;
}

std::uint32_t AdaptiveSqrt3::Hierarchy::face_point(std::uint32_t t) {
  if (tris_[t].point != kNone) return tris_[t].point;
  const std::uint32_t q = new_vertex(Origin::FacePoint, t, level(t) + 1);
  if (has_alpha_) {  // LL eq. 7
    const auto& v = tris_[t].v;
    alpha_[q] = (alpha_[v[0]] + alpha_[v[1]] + alpha_[v[2]]) / 3.0;
  }
  tris_[t].point = q;
  return q;
}

std::pair<std::uint32_t, std::uint32_t> AdaptiveSqrt3::Hierarchy::trisection(He s) {
  if (tris_[s.t].point == kNone) {
    const int l = level(s.t) + 1;
    const std::uint32_t m1 = new_vertex(Origin::NearFrom, s.t, l);
    const std::uint32_t m2 = new_vertex(Origin::NearTo, s.t, l);
    if (has_alpha_) {
      alpha_[m1] = (2.0 * alpha_[from(s)] + alpha_[to(s)]) / 3.0;
      alpha_[m2] = (alpha_[from(s)] + 2.0 * alpha_[to(s)]) / 3.0;
    }
    tris_[s.t].point = m1;
    tris_[s.t].point2 = m2;
    // The face across a crease shares them, seen from its own sharp half-edge.
    const He t = twin(s);
    if (t.valid()) {
      tris_[t.t].point = m2;
      tris_[t.t].point2 = m1;
    }
  }
  return {tris_[s.t].point, tris_[s.t].point2};
}

std::uint32_t AdaptiveSqrt3::Hierarchy::apex(He h) {
  const He s = trisects(level(h.t)) ? sharp_of(h.t) : He{};
  if (!s.valid()) return face_point(h.t);
  const auto [m1, m2] = trisection(s);
  return h == next(s) ? m2 : m1;
}

// ---------------------------------------------------------------------------------------
// Positions

He AdaptiveSqrt3::Hierarchy::home(std::uint32_t v) {
  if (verts_[v].home.valid() || verts_[v].origin == Origin::Input) return verts_[v].home;
  // The fine triangle whose corner 2 (its apex) is the new vertex.
  const std::uint32_t t = verts_[v].tri;
  He h{t, 0};
  if (verts_[v].origin != Origin::FacePoint) {
    const He s = sharp_of(t);
    h = verts_[v].origin == Origin::NearFrom ? prev(s) : next(s);
  }
  const He r{child(h), 2};
  if (from(r) != v) throw internal("a new vertex is not where its parent put it");
  verts_[v].home = r;
  return r;
}

He AdaptiveSqrt3::Hierarchy::halfedge_at(std::uint32_t v, int l) {
  He h = home(v);
  if (!h.valid()) return h;
  while (level(h.t) < l) {
    // A cut face's middle child does not touch from(s): go through the next face round.
    if (trisects(level(h.t)) && sharp(h)) h = twin(prev(h));
    h = {child(h), 0};
  }
  return h;
}

Vec3 AdaptiveSqrt3::Hierarchy::position(std::uint32_t v, int l) {
  const int own = verts_[v].level;
  l = interpolating_ ? own : std::clamp(l, own, top_level_);
  const std::uint32_t s = slot_of(v, l);
  if (known_[s]) return pool_[s];
  Vec3 p;
  if (l == own) {
    p = creation_position(v);
  } else {
    // The stencil's rule for an old vertex, on its fan one level coarser.
    const He h = halfedge_at(v, l - 1);
    std::vector<std::uint32_t> tris;
    gather_fan(h, tris);
    const Patch patch = build_patch(std::move(tris), l - 1);
    const auto local = static_cast<std::uint32_t>(
        std::lower_bound(patch.vertices.begin(), patch.vertices.end(), v) - patch.vertices.begin());
    p = stencil_.vertex_point(step_of(patch, l - 1), VertexId(local));
  }
  set_position(v, l, p);
  return p;
}

Vec3 AdaptiveSqrt3::Hierarchy::creation_position(std::uint32_t v) {
  const std::uint32_t t = verts_[v].tri;
  const int l = level(t);
  if (verts_[v].origin == Origin::FacePoint) {
    std::vector<std::uint32_t> tris{t};
    for (std::uint8_t k = 0; k < 3; ++k) gather_fan({t, k}, tris);
    const Patch patch = build_patch(std::move(tris), l);
    return stencil_.face_point(step_of(patch, l), FaceId(0));
  }
  // A trisection point: both points of the edge at once, from the edge's canonical half
  // (the one sqrt3_refine evaluates), so the results are the uniform level's bit for bit.
  He s = sharp_of(t);
  const auto [m1, m2] = trisection(s);
  const bool flipped = !canonical(s);
  if (flipped) {
    s = twin(s);
    if (!s.valid() || !canonical(s)) throw internal("a sharp edge has no canonical half");
  }
  std::vector<std::uint32_t> tris{s.t};
  gather_fan(s, tris);
  gather_fan(next(s), tris);
  const Patch patch = build_patch(std::move(tris), l);
  const std::array<Vec3, 2> pts = stencil_.curve_points(step_of(patch, l), HalfedgeId(s.k));
  set_position(flipped ? m2 : m1, l + 1, pts[0]);
  set_position(flipped ? m1 : m2, l + 1, pts[1]);
  return pts[v == m1 ? (flipped ? 1 : 0) : (flipped ? 0 : 1)];
}

void AdaptiveSqrt3::Hierarchy::gather_fan(He h, std::vector<std::uint32_t>& out) {
  // Counter-clockwise round from(h); at a boundary, clockwise from h as well.
  constexpr int kMaxValence = 1 << 16;
  He c = h;
  int steps = 0;
  bool open = false;
  do {
    out.push_back(c.t);
    const He t = twin(prev(c));
    if (!t.valid()) {
      open = true;
      break;
    }
    c = t;
    if (++steps > kMaxValence) throw internal("a vertex fan does not close");
  } while (!(c == h));
  if (!open) return;
  for (c = h;;) {
    const He t = twin(c);
    if (!t.valid()) break;
    c = next(t);
    out.push_back(c.t);
    if (++steps > kMaxValence) throw internal("a vertex fan does not close");
  }
}

AdaptiveSqrt3::Hierarchy::Patch AdaptiveSqrt3::Hierarchy::build_patch(
    std::vector<std::uint32_t> tris, int l) {
  // Local face i is the i-th distinct triangle (the target first).
  {
    std::vector<std::uint32_t> unique;
    unique.reserve(tris.size());
    for (std::uint32_t t : tris)
      if (std::find(unique.begin(), unique.end(), t) == unique.end()) unique.push_back(t);
    tris = std::move(unique);
  }
  std::vector<std::pair<std::uint32_t, std::uint32_t>> local_tri;  // (global, local) sorted
  local_tri.reserve(tris.size());
  for (std::uint32_t i = 0; i < tris.size(); ++i) local_tri.emplace_back(tris[i], i);
  std::sort(local_tri.begin(), local_tri.end());

  Patch p;
  for (std::uint32_t t : tris)
    for (std::uint32_t v : tris_[t].v) p.vertices.push_back(v);
  std::sort(p.vertices.begin(), p.vertices.end());
  p.vertices.erase(std::unique(p.vertices.begin(), p.vertices.end()), p.vertices.end());
  auto local_vertex = [&](std::uint32_t v) {
    return static_cast<std::uint32_t>(std::lower_bound(p.vertices.begin(), p.vertices.end(), v) -
                                      p.vertices.begin());
  };

  // Positions first: they may grow the hierarchy (coarser patches).
  BigVector<Vec3> positions(p.vertices.size());
  for (std::size_t i = 0; i < p.vertices.size(); ++i) positions[i] = position(p.vertices[i], l);

  BigVector<VertexId> corner(3 * tris.size());
  BigVector<HalfedgeId> twin_of(3 * tris.size());
  for (std::uint32_t i = 0; i < tris.size(); ++i) {
    const Tri& t = tris_[tris[i]];
    for (std::uint32_t k = 0; k < 3; ++k) {
      corner[3 * i + k] = VertexId(local_vertex(t.v[k]));
      const std::uint32_t n = t.nbr[k];
      if (n >= kUnknown) continue;  // a boundary, or an edge outside every fan walked
      const auto it = std::lower_bound(local_tri.begin(), local_tri.end(),
                                       std::pair<std::uint32_t, std::uint32_t>(n, 0));
      if (it != local_tri.end() && it->first == n)
        twin_of[3 * i + k] = HalfedgeId(3 * it->second + t.nbr_edge[k]);
    }
  }
  p.mesh = Mesh::from_parts(std::move(positions), std::move(corner), std::move(twin_of));
  BigVector<std::uint8_t> sharp(p.mesh.num_edges());
  for (std::uint32_t e = 0; e < sharp.size(); ++e) {
    const HalfedgeId h = p.mesh.halfedge(EdgeId(e));
    sharp[e] = (tris_[tris[h.idx / 3]].sharp >> (h.idx % 3)) & 1;
  }
  p.features = Features(p.mesh, std::move(sharp));
  if (trisects(l)) {
    p.sharp_corner.resize(tris.size());
    for (std::uint32_t i = 0; i < tris.size(); ++i) {
      const He s = sharp_of(tris[i]);
      p.sharp_corner[i] = s.valid() ? s.k : 3;
    }
  }
  if (has_alpha_) {
    p.alpha.resize(p.vertices.size());
    for (std::size_t i = 0; i < p.vertices.size(); ++i) p.alpha[i] = alpha_[p.vertices[i]];
  }
  return p;
}

// ---------------------------------------------------------------------------------------
// Driver

bool AdaptiveSqrt3::Hierarchy::wants_refinement(std::uint32_t t) {
  const int l = level(t);
  const std::array<std::uint32_t, 3> v = tris_[t].v;
  const Vec3 a = position(v[0], l), b = position(v[1], l), c = position(v[2], l);
  if (criteria_.angle_deg > 0) {
    const Vec3 n = triangle_normal(a, b, c);
    const double cos_limit = std::cos(criteria_.angle_deg * std::numbers::pi / 180.0);
    for (std::uint8_t k = 0; k < 3; ++k) {
      if (sharp({t, k})) continue;  // a crease is meant to be sharp
      const He tw = twin({t, k});
      if (!tw.valid()) continue;
      const std::array<std::uint32_t, 3> w = tris_[tw.t].v;
      const Vec3 m = triangle_normal(position(w[0], l), position(w[1], l), position(w[2], l));
      const double scale = std::sqrt(dot(n, n) * dot(m, m));
      if (scale > 0 && dot(n, m) < cos_limit * scale) return true;
    }
  }
  return criteria_.tol > 0 && deviation(t, criteria_.tol / kTail) > criteria_.tol / kTail;
}

void AdaptiveSqrt3::Hierarchy::cover(std::uint32_t t, std::vector<std::uint32_t>& out) {
  // The level l + 1 triangles over t: its children, and across every edge that is flipped
  // the child of the other side (the two make the flipped quad).
  for (std::uint8_t k = 0; k < 3; ++k) {
    const He h{t, k};
    out.push_back(child(h));
    if (makes_flip_child(h)) out.push_back(child(twin(h)));
  }
}

// Largest distance from `flat` of the piecewise-linear surface of level l + 2 over it, or
// a value above `limit` as soon as one is found. `fine` holds the level l + 1 triangles
// over `flat`; the level l + 2 triangles over those are clipped to the prism over `flat`
// and measured at the corners of what is left (the distance to a triangle is convex, so its
// largest over a polygon is at a corner). Across a sharp edge (bit k of `sharp`: edge k)
// there is no neighbour: the finer triangles never cross it, and what bulges beyond it (a
// crease or boundary curve bending in the plane) is this triangle's, so the prism is not cut
// there. With `folds`, a finer triangle over `flat` facing away from it counts as too far.
double AdaptiveSqrt3::Hierarchy::height_over(const std::array<Vec3, 3>& flat, std::uint8_t sharp,
                                             std::vector<std::uint32_t> fine, int l, double limit,
                                             bool folds) {
  constexpr double kInfinity = std::numeric_limits<double>::infinity();
  const Vec3 n = cross(flat[1] - flat[0], flat[2] - flat[0]);
  const double n2 = dot(n, n);
  if (!(n2 > 0)) return kInfinity;  // degenerate: refine it
  const double inv = 1.0 / std::sqrt(n2);
  std::vector<std::uint32_t> finer;
  for (std::uint32_t c : fine) cover(c, finer);
  std::sort(finer.begin(), finer.end());
  finer.erase(std::unique(finer.begin(), finer.end()), finer.end());
  std::array<Vec3, 3> wall;  // inward normals of the prism's sides
  for (int k = 0; k < 3; ++k) wall[k] = cross(n, flat[(k + 1) % 3] - flat[k]);
  auto distance_to_flat = [&](const Vec3& p, bool inside) {
    return inside ? std::abs(dot(p - flat[0], n)) * inv
                  : point_triangle_distance(p, flat[0], flat[1], flat[2]);
  };
  double worst = 0;
  for (std::uint32_t f : finer) {
    const std::array<std::uint32_t, 3> v = tris_[f].v;
    const std::array<Vec3, 3> p{position(v[0], l + 2), position(v[1], l + 2),
                                position(v[2], l + 2)};
    // Side of every wall for every corner; the common case is a triangle inside the prism.
    std::array<std::array<double, 3>, 3> side{};
    bool cut = false, beyond = false;
    for (int k = 0; k < 3; ++k) {
      int out = 0;
      for (int i = 0; i < 3; ++i) {
        side[i][k] = dot(p[i] - flat[k], wall[k]);
        out += side[i][k] < 0;
      }
      if ((sharp >> k) & 1) continue;
      cut |= out > 0;
      beyond |= out == 3;
    }
    if (beyond) continue;  // wholly outside the prism
    if (!cut) {
      for (int i = 0; i < 3; ++i) {
        bool in = true;
        for (int k = 0; k < 3; ++k) in = in && side[i][k] >= 0;
        worst = std::max(worst, distance_to_flat(p[i], in));
      }
    } else {  // Sutherland-Hodgman against the non-sharp sides
      std::array<Vec3, 9> poly{p[0], p[1], p[2]}, clipped;
      std::size_t count = 3;
      for (int k = 0; k < 3 && count > 0; ++k) {
        if ((sharp >> k) & 1) continue;
        std::size_t m = 0;
        for (std::size_t i = 0; i < count; ++i) {
          const Vec3& a = poly[i];
          const Vec3& b = poly[(i + 1) % count];
          const double da = dot(a - flat[k], wall[k]), db = dot(b - flat[k], wall[k]);
          if (da >= 0) clipped[m++] = a;
          if ((da >= 0) != (db >= 0)) clipped[m++] = a + (da / (da - db)) * (b - a);
        }
        poly = clipped;
        count = m;
      }
      if (count == 0) continue;
      // Inside every side that was cut; without sharp sides, inside the prism.
      for (std::size_t i = 0; i < count; ++i)
        worst = std::max(worst, distance_to_flat(poly[i], sharp == 0));
    }
    if (folds && dot(cross(p[1] - p[0], p[2] - p[0]), n) <= 0) return kInfinity;
    if (worst > limit) return worst;
  }
  return worst;
}

double AdaptiveSqrt3::Hierarchy::deviation(std::uint32_t t, double limit) {
  // How far the surface of two levels finer lies from t. Two levels, because one adds only
  // the face point, which sees no curvature along t's edges; after two every edge is
  // trisected. The finer *surface*, not only its new points: on irregular meshes the new
  // points of two steps can all lie away from t's edges, while the limit surface is often
  // farthest from t at the middle of an edge (measured on bunny_low: the points within tol,
  // the uniform level at the cap 1.65 tol away there; see bench/RESULTS.md "## sqrt3").
  const int l = level(t);
  const std::array<std::uint32_t, 3> v = tris_[t].v;
  std::vector<std::uint32_t> fine;
  cover(t, fine);
  return height_over({position(v[0], l), position(v[1], l), position(v[2], l)}, tris_[t].sharp,
                     std::move(fine), l, limit, false);
}

double AdaptiveSqrt3::Hierarchy::piece_deviation(He h, double limit) {
  // The piece (from, to, apex) of a refined triangle whose edge h is not flipped yet, because
  // the triangle across is not refined. It lies over the flipped quad of h. Its sharp edges,
  // as result() marks them: in a trisecting level the two next to the cut sharp edge s are
  // thirds of it. Where a finer triangle over it folds over (the apex can lie outside the
  // quad on thin triangles: OpenSCAD's polar fans), points of the finer surface can lie
  // outside the prism of every output face; measured 1.01 tol on sphere_fn16.
  const int l = level(h.t);
  const He s = trisects(l) ? sharp_of(h.t) : He{};
  std::uint8_t sharp_bits = 0;
  if (s.valid() && h == prev(s)) sharp_bits |= 2;
  if (s.valid() && h == next(s)) sharp_bits |= 4;
  std::vector<std::uint32_t> fine{child(h), child(twin(h))};
  return height_over({position(from(h), l), position(to(h), l), position(apex(h), l + 1)},
                     sharp_bits, std::move(fine), l, limit, true);
}

bool AdaptiveSqrt3::Hierarchy::refine_across_pieces_over_tolerance() {
  // A piece is an output face too: where one is too far from the surface, refine the
  // triangle across, which flips the edge and replaces the piece by finer triangles. A
  // piece, once measured, keeps its measure: the triangle across can only become refined.
  std::vector<std::uint32_t> across;
  auto add = [&](std::uint32_t t) {
    if (across.size() == across.capacity()) {  // reserved before it doubles
      const std::size_t capacity = std::max<std::size_t>(1024, 2 * across.capacity());
      need(held_bytes() + capacity * sizeof(std::uint32_t));
      across.reserve(capacity);
      transient_bytes_ = capacity * sizeof(std::uint32_t);
    }
    across.push_back(t);
  };
  const auto count = static_cast<std::uint32_t>(tris_.size());
  for (std::uint32_t t = 0; t < count; ++t) {
    if (!refined(t) || flag(t, kPiecesChecked)) continue;
    tris_[t].flags |= kPiecesChecked;
    for (std::uint8_t k = 0; k < 3; ++k) {
      const He h{t, k};
      if (!makes_flip_child(h)) continue;
      const He tw = twin(h);
      if (refined(tw.t)) continue;
      throw_if_cancelled();
      const double limit = criteria_.tol / kTail;
      if (piece_deviation(h, limit) > limit) add(tw.t);
    }
  }
  for (std::uint32_t t : across) {
    if (refined(t)) continue;
    const std::size_t before = refined_count_;
    refine(t);
    ++stats_.refined_by_criterion;
    stats_.refined_by_closure += refined_count_ - before - 1;
  }
  transient_bytes_ = 0;
  return !across.empty();
}

void AdaptiveSqrt3::Hierarchy::refine(std::uint32_t t) {
  if (refined(t)) return;
  ensure_exists(t);
  // Spec 3.6 step 1: every level-l triangle around t's corners exists (its stencil is in
  // the mesh). Either way every edge neighbour exists, so the result conforms.
  std::vector<std::uint32_t> around;
  for (std::uint8_t k = 0; k < 3; ++k) {
    if (criteria_.closure == Sqrt3Closure::Stencil) {
      gather_fan({t, k}, around);
    } else if (const He tw = twin({t, k}); tw.valid()) {
      around.push_back(tw.t);
    }
  }
  for (std::uint32_t u : around) ensure_exists(u);
  if (refined(t)) throw internal("a triangle was refined while its neighbourhood was made");

  // One split adds two faces; flips change no count.
  const std::uint64_t faces = input_faces_ + 2 * (refined_count_ + 1);
  if (faces > max_faces_)
    throw Error(
        ErrorCode::BudgetExceeded, "face_budget",
        "adaptive refinement would make more than max_faces = " + std::to_string(max_faces_) +
            " faces (stopped at " + std::to_string(faces - 2) + ")")
        .with_field("max_faces");
  throw_if_cancelled();
  tris_[t].flags |= kRefined;
  ++refined_count_;

  // The triangles that exist now: children kept whole, and both flip children of every old
  // edge whose other side was refined before.
  for (std::uint8_t k = 0; k < 3; ++k) {
    const He h{t, k};
    if (!makes_flip_child(h)) {
      enqueue(child(h));
      continue;
    }
    const He tw = twin(h);
    if (!refined(tw.t)) continue;
    enqueue(child(h));
    enqueue(child(tw));
  }
  // A sharp edge is trisected on both of its sides at once (no T-junction).
  if (trisects(level(t))) {
    const He s = sharp_of(t);
    const He across = s.valid() ? twin(s) : He{};
    if (across.valid()) refine(across.t);
  }
}

void AdaptiveSqrt3::Hierarchy::run(std::uint64_t max_faces, const std::atomic<bool>* cancel,
                                   const std::function<void(int)>& level_started) {
  max_faces_ = max_faces;
  cancel_ = cancel;
  scope_cancel_ = detail::current_cancel_flag;
  if (input_faces_ > max_faces)
    throw Error(ErrorCode::BudgetExceeded, "face_budget",
                "the input has more than max_faces = " + std::to_string(max_faces) + " faces")
        .with_field("max_faces");
  for (std::uint32_t t = 0; t < input_faces_; ++t) enqueue(t);
  int announced = -1;
  for (;;) {
    int l = 0;
    while (l < static_cast<int>(queue_.size()) && queue_[l].empty()) ++l;
    if (l == static_cast<int>(queue_.size())) {
      if (criteria_.tol > 0 && refine_across_pieces_over_tolerance()) continue;
      break;
    }
    if (l > announced) {
      announced = l;
      if (level_started) level_started(l);
    }
    const std::uint32_t t = queue_[l].front();
    queue_[l].pop_front();
    throw_if_cancelled();
    if (refined(t) || !wants_refinement(t)) continue;
    const std::size_t before = refined_count_;
    refine(t);
    ++stats_.refined_by_criterion;
    stats_.refined_by_closure += refined_count_ - before - 1;
  }
  // At the cap some faces may still ask for more: say how many. Measuring a face at the
  // cap makes the two levels below it, which nothing else needs: up to 9 triangles per
  // face, several times the whole hierarchy. They are dropped in batches (an eighth of the
  // hierarchy) and remade where the next batch needs them again. Every face at the cap
  // exists already (refine() makes the children it brings into existence).
  const Checkpoint mark = checkpoint();
  const std::uint64_t base = held_bytes();
  const std::uint64_t batch = std::max<std::uint64_t>(base / 8, std::uint64_t{16} << 20);
  for (std::uint32_t t = 0; t < mark.tris; ++t) {
    if (level(t) != criteria_.max_level || refined(t) || !exists(t)) continue;
    throw_if_cancelled();
    if (wants_refinement(t)) ++stats_.over_criterion_at_cap;
    if (held_bytes() > base + batch) rollback(mark);
  }
  rollback(mark);
}

void AdaptiveSqrt3::Hierarchy::rollback(const Checkpoint& c) {
  // Everything made after the checkpoint goes; so do the links older triangles and
  // vertices got to it (children, neighbours, face and trisection points, homes). They are
  // all caches of what the uniform hierarchy is: made again, they come out the same.
  const auto tris = static_cast<std::uint32_t>(c.tris);
  const auto verts = static_cast<std::uint32_t>(c.verts);
  for (std::uint32_t t = 0; t < tris; ++t) {
    Tri& x = tris_[t];
    for (int k = 0; k < 3; ++k) {
      if (x.child[k] != kNone && x.child[k] >= tris) x.child[k] = kNone;
      if (x.nbr[k] < kUnknown && x.nbr[k] >= tris) x.nbr[k] = kUnknown;
    }
    if (x.point != kNone && x.point >= verts) x.point = kNone;
    if (x.point2 != kNone && x.point2 >= verts) x.point2 = kNone;
  }
  for (std::uint32_t v = 0; v < verts; ++v)
    if (verts_[v].home.valid() && verts_[v].home.t >= tris) verts_[v].home = He{};
  tris_.truncate(c.tris);
  verts_.truncate(c.verts);
  alpha_.truncate(c.verts);
  pool_.truncate(c.slots);
  known_.truncate(c.slots);
}

Level AdaptiveSqrt3::Hierarchy::result(std::vector<std::uint8_t>* face_level) {
  // Built in phases, each reserved before it allocates. transient_bytes_ holds what the
  // phase has alive besides the hierarchy, which may still grow meanwhile (positions of
  // approximating stencils, neighbours looked up), so its chunks are reserved on top.
  const std::size_t num_faces = input_faces_ + 2 * refined_count_;  // a split adds two
  const std::size_t nh = 3 * num_faces;
  auto phase = [&](std::uint64_t bytes) {
    transient_bytes_ = bytes;
    need(held_bytes());
  };
  using Face = std::array<std::uint32_t, 3>;
  const std::uint64_t face_list = num_faces * sizeof(Face);
  const std::uint64_t face_bits = 2 * std::uint64_t(num_faces);  // sharp bits, levels
  phase(face_list + face_bits);

  std::vector<Face> faces;
  std::vector<std::uint8_t> sharp_bits, levels;
  faces.reserve(num_faces);
  sharp_bits.reserve(num_faces);
  levels.reserve(num_faces);
  for (std::uint32_t t = 0; t < tris_.size(); ++t) {
    if (!exists(t)) continue;
    const int l = level(t);
    if (!refined(t)) {
      faces.push_back(tris_[t].v);
      sharp_bits.push_back(tris_[t].sharp);
      levels.push_back(static_cast<std::uint8_t>(l));
      continue;
    }
    // Where the old edge is not flipped yet: the split's piece (from, to, apex).
    const He s = trisects(l) ? sharp_of(t) : He{};
    for (std::uint8_t k = 0; k < 3; ++k) {
      const He h{t, k};
      if (!makes_flip_child(h) || refined(twin(h).t)) continue;
      faces.push_back({from(h), to(h), apex(h)});
      std::uint8_t bits = sharp(h) ? 1 : 0;
      if (s.valid() && h == prev(s)) bits |= 2;  // to(h) -> m1: the first third of s
      if (s.valid() && h == next(s)) bits |= 4;  // m2 -> from(h): the last third of s
      sharp_bits.push_back(bits);
      levels.push_back(static_cast<std::uint8_t>(l + 1));
    }
  }
  if (faces.size() != num_faces) throw internal("the output face count is not the predicted one");

  // Input vertices keep their ids; the new vertices in use follow in creation order.
  const std::size_t nv = verts_.size();
  const std::uint64_t vertex_ids = nv * (sizeof(std::uint32_t) + 1);
  phase(face_list + face_bits + vertex_ids);
  std::vector<std::uint32_t> out_id(nv, kNone);
  std::vector<std::uint8_t> vertex_level(nv, 0);
  for (std::uint32_t v = 0; v < input_vertices_; ++v) out_id[v] = v;
  for (std::size_t f = 0; f < faces.size(); ++f)
    for (std::uint32_t v : faces[f]) vertex_level[v] = std::max(vertex_level[v], levels[f]);
  std::size_t nu = input_vertices_;
  for (const Face& f : faces)
    for (std::uint32_t v : f)
      if (out_id[v] == kNone) out_id[v] = 0, ++nu;
  const std::uint64_t vertex_arrays =
      big_vector_bytes<Vec3>(nu) + (has_alpha_ ? big_vector_bytes<double>(nu) : 0);
  phase(face_list + face_bits + vertex_ids + nu * sizeof(std::uint32_t) + vertex_arrays);
  std::vector<std::uint32_t> used;
  used.reserve(nu);
  for (std::uint32_t v = 0; v < input_vertices_; ++v) used.push_back(v);
  for (std::uint32_t v = input_vertices_; v < nv; ++v)
    if (out_id[v] != kNone) used.push_back(v);
  BigVector<Vec3> positions(used.size());
  BigVector<double> alpha(has_alpha_ ? used.size() : 0);
  for (std::uint32_t i = 0; i < used.size(); ++i) {
    out_id[used[i]] = i;
    positions[i] = position(used[i], vertex_level[used[i]]);
    if (has_alpha_) alpha[i] = alpha_[used[i]];
  }
  std::vector<std::uint32_t>().swap(used);
  std::vector<std::uint8_t>().swap(vertex_level);

  const std::uint64_t corners = big_vector_bytes<VertexId>(nh);
  phase(face_list + face_bits + nv * sizeof(std::uint32_t) + vertex_arrays + corners);
  BigVector<VertexId> corner(nh);
  for (std::size_t f = 0; f < faces.size(); ++f)
    for (std::size_t k = 0; k < 3; ++k) corner[3 * f + k] = VertexId(out_id[faces[f][k]]);
  std::vector<Face>().swap(faces);
  std::vector<std::uint32_t>().swap(out_id);

  // Twins: each vertex's outgoing half-edges sorted by where they go (a counting sort by
  // vertex, then each short list), so h = a -> b finds b -> a by a binary search in b's.
  const std::uint64_t twins = big_vector_bytes<HalfedgeId>(nh);
  phase(face_bits + vertex_arrays + corners + (nu + 1 + nh) * sizeof(std::uint32_t) + twins);
  BigVector<HalfedgeId> twin_of(nh);
  {
    auto target = [&](std::uint32_t h) { return corner[Mesh::next(HalfedgeId(h)).idx].idx; };
    std::vector<std::uint32_t> first(nu + 1, 0), outgoing(nh);
    for (std::uint32_t h = 0; h < nh; ++h) ++first[corner[h].idx + 1];
    for (std::size_t v = 0; v < nu; ++v) first[v + 1] += first[v];
    for (std::uint32_t h = 0; h < nh; ++h) outgoing[first[corner[h].idx]++] = h;
    for (std::size_t v = nu; v > 0; --v) first[v] = first[v - 1];
    first[0] = 0;
    auto by_target = [&](std::uint32_t g, std::uint32_t h) { return target(g) < target(h); };
    for (std::size_t v = 0; v < nu; ++v) {
      const auto begin = outgoing.begin() + first[v], end = outgoing.begin() + first[v + 1];
      std::sort(begin, end, by_target);
      if (std::adjacent_find(begin, end, [&](std::uint32_t g, std::uint32_t h) {
            return target(g) == target(h);
          }) != end)
        throw internal("the refined mesh repeats a directed edge");
    }
    for (std::uint32_t h = 0; h < nh; ++h) {
      const std::uint32_t a = corner[h].idx, b = target(h);
      const auto begin = outgoing.begin() + first[b], end = outgoing.begin() + first[b + 1];
      const auto it = std::lower_bound(
          begin, end, a, [&](std::uint32_t g, std::uint32_t want) { return target(g) < want; });
      if (it != end && target(*it) == a) twin_of[h] = HalfedgeId(*it);
    }
  }

  const std::size_t edge_reserve = nh / 2 + 1;  // Mesh::from_parts doubles it at a boundary
  phase(face_bits + vertex_arrays + corners + twins + big_vector_bytes<EdgeId>(nh) +
        big_vector_bytes<HalfedgeId>(edge_reserve) +
        big_vector_bytes<HalfedgeId>(2 * edge_reserve) + big_vector_bytes<HalfedgeId>(nu) +
        big_vector_bytes<std::uint8_t>(nh) + big_vector_bytes<VertexKind>(nu) +
        big_vector_bytes<std::array<VertexId, 2>>(nu));
  Level out;
  out.mesh = Mesh::from_parts(std::move(positions), std::move(corner), std::move(twin_of));
  BigVector<std::uint8_t> sharp(out.mesh.num_edges());
  for (std::uint32_t e = 0; e < sharp.size(); ++e) {
    const HalfedgeId h = out.mesh.halfedge(EdgeId(e));
    sharp[e] = (sharp_bits[h.idx / 3] >> (h.idx % 3)) & 1;
  }
  out.features = Features(out.mesh, std::move(sharp));
  out.alpha = std::move(alpha);
  stats_.levels = levels.empty() ? 0 : *std::max_element(levels.begin(), levels.end());
  transient_bytes_ = 0;
  if (face_level) *face_level = std::move(levels);
  return out;
}

// ---------------------------------------------------------------------------------------

AdaptiveSqrt3::AdaptiveSqrt3(const Level& coarse, const Sqrt3Stencil& stencil,
                             const Sqrt3AdaptiveCriteria& criteria,
                             std::function<void(std::uint64_t)> reserve)
    : h_(std::make_unique<Hierarchy>(coarse, stencil, criteria, std::move(reserve))) {
  if (coarse.step != 0) throw internal("the adaptive mode starts from an input level");
  if (criteria.max_level < 1 || criteria.max_level > 8) throw internal("max_level outside [1, 8]");
}

AdaptiveSqrt3::~AdaptiveSqrt3() = default;

void AdaptiveSqrt3::run(std::uint64_t max_faces, const std::atomic<bool>* cancel,
                        const std::function<void(int)>& level_started) {
  h_->run(max_faces, cancel, level_started);
}

Level AdaptiveSqrt3::result(std::vector<std::uint8_t>* face_level) {
  return h_->result(face_level);
}

const Sqrt3AdaptiveStats& AdaptiveSqrt3::stats() const {
  return h_->stats();
}

}  // namespace stlrefine
