// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// The adaptive sqrt3 host's hierarchy (adaptive_sqrt3.h), shared by its three source files:
// adaptive_sqrt3_topology.cpp (the uniform hierarchy's connectivity and positions, made on
// demand), adaptive_sqrt3.cpp (the driver: criteria, refinement, closure) and
// adaptive_sqrt3_result.cpp (the conforming output mesh). Internal to core/schemes.
//
// The hierarchy speaks core/mesh's handles: triangle t is FaceId t, its half-edge k is
// HalfedgeId(3t + k) (Mesh::next / prev / face apply), a vertex is a VertexId (input vertex
// v is VertexId v, new vertices follow).
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "core/error.h"
#include "core/mesh/handles.h"
#include "core/mesh/mesh.h"
#include "core/schemes/adaptive_sqrt3.h"
#include "core/schemes/sqrt3_degenerate.h"

namespace stlrefine::adaptive_sqrt3_detail {

//! A twin not looked up yet (HalfedgeId::invalid() is a boundary). Never a real half-edge:
//! kMaxTriangles keeps 3t + k below it.
inline constexpr HalfedgeId kUnknownTwin{HalfedgeId::kInvalid - 1};
//! Triangles the hierarchy may hold: their half-edges 3t + k stay below kUnknownTwin.
inline constexpr std::size_t kMaxTriangles = (std::size_t{HalfedgeId::kInvalid} - 2) / 3;

inline std::uint8_t corner_of(HalfedgeId h) {
  return static_cast<std::uint8_t>(h.idx % 3);
}

enum TriFlag : std::uint8_t {
  kRefined = 1,        // split (1-to-3, or cut at a sharp edge's trisection points)
  kFlip = 2,           // made by a flip: exists once the triangles on both sides are refined
  kQueued = 4,         // in the driver's queue
  kPiecesChecked = 8,  // refined, and its pieces (edges not flipped yet) were measured
  kNormalKnown = 16,   // << k: the sector normal at corner k is in corner_normal_ (guarded)
};

//! A triangle of the uniform hierarchy at its level. Corner order, neighbours and children
//! follow sqrt3_refine's layout: child k is the fine face of half-edge k.
struct Tri {
  std::array<VertexId, 3> v{};
  std::array<HalfedgeId, 3> twin{kUnknownTwin, kUnknownTwin, kUnknownTwin};  // invalid: boundary
  std::array<FaceId, 3> child{};
  HalfedgeId owner;  // the coarser half-edge that made it
  VertexId point;    // face point, or the trisection point nearest from(s)
  VertexId point2;   // the trisection point nearest to(s)
  std::uint8_t level = 0;
  std::uint8_t sharp = 0;  // bit k: edge k is sharp
  std::uint8_t canon = 0;  // bit k: sharp edge k is its edge's canonical half in sqrt3_refine
  std::uint8_t flags = 0;
  //! The fold guard's decision per edge k (sqrt3_host's keep_folding_flips): bit k: decided,
  //! bit 3 + k: the edge is not flipped although both of its sides are refined. `keep` is
  //! the last pass's (the topology), keep_first the first pass's.
  std::uint8_t keep = 0;
  std::uint8_t keep_first = 0;
};

//! The fold guard's rounds (adaptive_sqrt3_guard.cpp): round 0 pulls a face point where a
//! fine face round it folds with its neighbours' stencil points; round r where one folds
//! with their points of round r - 1, from its own stage of round r - 1 on. The last round's
//! point (of the last pass) is its position.
inline constexpr int kGuardRounds = 4;

//! The guard's two passes over the flips: pass 0 keeps the flips that fold with the
//! stencil's points; pass 1 also those that fold with pass 0's pulled points (the uniform
//! host's later rounds). The hierarchy's topology is pass 1's.
inline constexpr int kGuardPasses = 2;

//! A face point's stencil point and its pull stage per pass and round (the point of a
//! stage is cheap to remake from the stencil point and the face's corners).
struct GuardPoint {
  Vec3 stencil{};
  std::array<std::array<std::uint8_t, kGuardRounds>, kGuardPasses> stage{};
  bool stencil_known = false;
  std::array<std::uint8_t, kGuardPasses> known{};  // bit r: stage[pass][r] is known
};

enum class Origin : std::uint8_t { Input, FacePoint, NearFrom, NearTo };

struct Vert {
  FaceId tri;              // the triangle whose face point / trisection point it is
  std::uint32_t slot = 0;  // first of its positions in the pool
  HalfedgeId home;         // a half-edge from it at its own level (invalid: not known yet)
  Origin origin = Origin::Input;
  std::uint8_t level = 0;
  bool pulled = false;  // a face point the fold guard moved off the stencil's point
};

//! The criterion measures the surface two levels finer; the levels after those add a tail.
//! Per double step the deviation from the flat shrinks at least by the largest eigenvalue
//! of the double step's subdivision matrix below the affine 1, 1/3, 1/3: 0.180019 at
//! valence 6, 1/9 at the others, 11/81 on curves (Labsik-Greiner; spec 3.2-3.4,
//! bench/RESULTS.md "## sqrt3"; sqrt3-unified with alpha 1: 0.160 at valence 6). The whole
//! deviation is then at most 1 / (1 - 0.180019) = 1.22 times the measured one in the
//! asymptotic regime; on coarse irregular meshes it was measured, not proven (tests:
//! bunny_low, sphere_fn16).
inline constexpr double kTail = 1.0 / (1.0 - 0.180019);

//! The heap a stencil patch takes per face (its small mesh, features and index arrays,
//! about 130 B) with room for allocator headers, and per patch.
inline constexpr std::uint64_t kPatchFaceBytes = 256;
inline constexpr std::uint64_t kPatchBytes = 4096;

inline Error internal(const std::string& what) {
  std::string message = "adaptive sqrt3: ";
  message.append(what);
  return Error(ErrorCode::Internal, "adaptive_sqrt3", message);
}

//! The hierarchy's arrays: they grow a chunk at a time and never move. A vector holds its
//! old and new buffers while it doubles and keeps up to twice what it uses; these hold what
//! they use rounded up to one chunk, and memory admission reserves them a chunk at a time.
//! References to elements stay valid while it grows. Indexed by position or by a handle.
template <class T>
class Chunked {
 public:
  static constexpr int kShift = 14;
  static constexpr std::size_t kChunk = std::size_t{1} << kShift;
  static constexpr std::uint64_t kChunkBytes = sizeof(T) * kChunk;

  T& operator[](std::size_t i) { return chunks_[i >> kShift][i & (kChunk - 1)]; }
  const T& operator[](std::size_t i) const { return chunks_[i >> kShift][i & (kChunk - 1)]; }
  template <class Tag>
  T& operator[](Handle<Tag> i) {
    return (*this)[std::size_t{i.idx}];
  }
  template <class Tag>
  const T& operator[](Handle<Tag> i) const {
    return (*this)[std::size_t{i.idx}];
  }
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

}  // namespace stlrefine::adaptive_sqrt3_detail

namespace stlrefine {

class AdaptiveSqrt3::Hierarchy {
 public:
  Hierarchy(const Level& coarse, const Sqrt3Stencil& stencil, const Sqrt3AdaptiveCriteria& c,
            std::function<void(std::uint64_t)> reserve);

  void run(std::uint64_t max_faces, const std::atomic<bool>* cancel,
           const std::function<void(int)>& level_started);
  Level result(std::vector<std::uint8_t>* face_level);
  const Sqrt3AdaptiveStats& stats() const { return stats_; }

 private:
  using Tri = adaptive_sqrt3_detail::Tri;
  using Vert = adaptive_sqrt3_detail::Vert;
  using Origin = adaptive_sqrt3_detail::Origin;
  using TriFlag = adaptive_sqrt3_detail::TriFlag;
  template <class T>
  using Chunked = adaptive_sqrt3_detail::Chunked<T>;

  // --- the hierarchy's connectivity (mirrors sqrt3_refine's Sqrt3Layout)

  static bool trisects(int level) { return level % 2 == 1; }
  static HalfedgeId he(FaceId t, std::uint8_t k) { return Mesh::halfedge(t, k); }
  int level(FaceId t) const { return tris_[t].level; }
  bool flag(FaceId t, TriFlag f) const { return (tris_[t].flags & f) != 0; }
  bool refined(FaceId t) const { return flag(t, adaptive_sqrt3_detail::kRefined); }
  VertexId from(HalfedgeId h) const {
    return tris_[Mesh::face(h)].v[adaptive_sqrt3_detail::corner_of(h)];
  }
  VertexId to(HalfedgeId h) const { return from(Mesh::next(h)); }
  VertexId opposite(HalfedgeId h) const { return from(Mesh::prev(h)); }
  bool sharp(HalfedgeId h) const {
    return (tris_[Mesh::face(h)].sharp >> adaptive_sqrt3_detail::corner_of(h)) & 1;
  }
  bool canonical(HalfedgeId h) const {
    return (tris_[Mesh::face(h)].canon >> adaptive_sqrt3_detail::corner_of(h)) & 1;
  }

  // In a trisecting level, the face's one sharp half-edge (invalid: none).
  HalfedgeId sharp_of(FaceId t) const;
  // The edge of h is not flipped: sharp (in a trisecting level: cut), on the boundary, or
  // left unflipped by the fold guard (sqrt3_host's Sqrt3Layout::kept).
  // Without the guard the twins are looked up in the order the hierarchy always did (a
  // trisecting level has no boundary edge that is not sharp), so the output is the same
  // bit for bit, vertex numbering included.
  bool kept(HalfedgeId h, int pass = adaptive_sqrt3_detail::kGuardPasses - 1) {
    if (sharp(h)) return true;
    if (!guarded_) return !trisects(level(Mesh::face(h))) && !twin(h).valid();
    return !twin(h).valid() || unflipped(h, pass);
  }
  // Both sides refined: an old edge is flipped, a kept one is not.
  bool makes_flip_child(HalfedgeId h) { return !kept(h); }
  // The fold guard's topological half (adaptive_sqrt3_guard.cpp), decided once per edge.
  bool unflipped(HalfedgeId h, int pass);
  // With the face points of the pass before `pass`, the stencil's for pass 0.
  bool flip_folds(HalfedgeId h, int pass);
  Vec3 sector_normal(HalfedgeId h);
  Vec3 apex_normal(HalfedgeId h);
  // Which points a guard decision sees: the face points' of pass `pass`, round `round`
  // (pass -1: the stencil's, before any pull, as in the uniform host's first round).
  struct View {
    int pass = -1, round = 0;
  };
  // Fine triangle c of `level`, made from the triangles f and g of the level before (f twice
  // for a child of one), folds against `smooth` or is degenerate (sqrt3_degenerate.h).
  bool folds(const std::array<VertexId, 3>& c, int level, const Vec3& smooth, FaceId f, FaceId g,
             View view, VertexId moved = VertexId(), const Vec3& at = Vec3{});
  Sqrt3Shape shape(FaceId t);
  // The geometric half, for one face point: where a fine face round it folds, it moves.
  // The stage it stopped at in round `round` of pass `pass`, and its point there.
  int guard_stage(VertexId q, int pass, int round);
  Vec3 stage_point(VertexId q, int stage);
  Vec3 guard_view(VertexId v, int level, View view);
  Vec3 stencil_face_point(VertexId q);
  // sqrt3_host's Sqrt3Layout::to_apex and set_to_apex_side: the fine half-edge to(x) ->
  // apex(x), and the one across it inside face(x).
  HalfedgeId to_apex(HalfedgeId x) {
    const HalfedgeId t = twin(x);
    return kept(x) ? fine(x, 1) : fine(t, 0);
  }
  HalfedgeId to_apex_side(HalfedgeId x);

  HalfedgeId twin(HalfedgeId h);
  HalfedgeId derive_twin(HalfedgeId h);
  HalfedgeId fine(HalfedgeId h, std::uint8_t k) { return he(child(h), k); }
  FaceId child(HalfedgeId h);
  VertexId face_point(FaceId t);
  std::pair<VertexId, VertexId> trisection(HalfedgeId s);
  VertexId apex(HalfedgeId h);

  bool exists(FaceId t) {
    if (level(t) == 0) return true;
    const HalfedgeId owner = tris_[t].owner;
    if (!refined(Mesh::face(owner))) return false;
    return !flag(t, adaptive_sqrt3_detail::kFlip) || refined(Mesh::face(twin(owner)));
  }

  // --- vertices and positions

  VertexId new_vertex(Origin origin, FaceId tri, int level);
  FaceId add_tri(const Tri& t);

  // --- memory (see AdaptiveSqrt3's comment)

  //! Everything the hierarchy holds now, and what may be alive besides at any moment.
  std::uint64_t held_bytes() const {
    // The queues hold each triangle at most once: 4 B each, their blocks and maps about 2 %
    // more, and a partly used block per queue.
    const std::uint64_t queues = 5 * std::uint64_t(tris_.capacity()) + queue_.size() * 2048;
    return tris_.bytes() + verts_.bytes() + pool_.bytes() + known_.bytes() + alpha_.bytes() +
           guard_point_.bytes() + corner_normal_.bytes() + queues + patch_bytes_ + transient_bytes_;
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
  std::uint32_t slot_of(VertexId v, int level) const {
    const Vert& info = verts_[v];
    return info.slot + (interpolating_ ? 0 : static_cast<std::uint32_t>(level - info.level));
  }
  void set_position(VertexId v, int level, const Vec3& p) {
    const std::uint32_t s = slot_of(v, level);
    pool_[s] = p;
    known_[s] = 1;
  }
  Vec3 position(VertexId v, int level);
  Vec3 creation_position(VertexId v);
  HalfedgeId home(VertexId v);
  HalfedgeId halfedge_at(VertexId v, int level);

  // --- stencil evaluation on a patch of one level

  struct Patch {
    Mesh mesh;
    Features features;
    BigVector<double> alpha;
    //! Trisecting levels: per local face, its sharp edge (Sqrt3Step::sharp_corner) from
    //! the hierarchy's flags: the patch's own features also call the edges where the
    //! patch ends sharp (they are its boundary).
    BigVector<std::uint8_t> sharp_corner;
    std::vector<VertexId> vertices;  // local -> global, sorted
  };
  void gather_fan(HalfedgeId h, std::vector<FaceId>& out);
  Patch build_patch(std::vector<FaceId> tris, int level);
  Sqrt3Step step_of(const Patch& p, int level) const {
    return Sqrt3Step{p.mesh, p.features, trisects(level), p.alpha, p.sharp_corner};
  }

  // --- the driver

  bool wants_refinement(FaceId t);
  void cover(FaceId t, std::vector<FaceId>& out);
  double height_over(const std::array<Vec3, 3>& flat, std::uint8_t sharp, std::vector<FaceId> fine,
                     int l, double limit, bool folds);
  double deviation(FaceId t, double limit);
  double piece_deviation(HalfedgeId h, double limit);
  bool refine_across_pieces_over_tolerance();
  void refine(FaceId t);
  void ensure_exists(FaceId t) {
    if (level(t) == 0) return;
    const HalfedgeId owner = tris_[t].owner;
    refine(Mesh::face(owner));
    if (flag(t, adaptive_sqrt3_detail::kFlip)) refine(Mesh::face(twin(owner)));
  }
  // A DELETE'd job, a deadline or a client that hung up raises the flag passed to run()
  // or the caller's CancelScope. Checked before every triangle is examined and before every
  // split: one check is a relaxed load, far cheaper than either.
  void throw_if_cancelled() const {
    for (const std::atomic<bool>* flag : {cancel_, scope_cancel_})
      if (flag && flag->load(std::memory_order_relaxed))
        throw Error(ErrorCode::Cancelled, "cancelled", "refinement cancelled");
  }
  void enqueue(FaceId t) {
    if (flag(t, adaptive_sqrt3_detail::kQueued) || level(t) >= criteria_.max_level) return;
    tris_[t].flags |= adaptive_sqrt3_detail::kQueued;
    queue_[level(t)].push_back(t);
  }

  const Sqrt3Stencil& stencil_;
  Sqrt3AdaptiveCriteria criteria_;
  bool interpolating_;
  bool guarded_;  // the stencil asks for the fold guard (as sqrt3_refine's FoldGuard::AsStencil)
  double cos_fold_;
  bool has_alpha_ = false;
  int top_level_;  // the finest level any position is asked for (two past the cap)
  std::uint32_t input_vertices_;
  std::size_t input_faces_;

  Chunked<Tri> tris_;
  Chunked<Vert> verts_;
  Chunked<Vec3> pool_;
  Chunked<std::uint8_t> known_;
  Chunked<double> alpha_;
  Chunked<adaptive_sqrt3_detail::GuardPoint> guard_point_;  // guarded: per vertex
  // Guarded: per triangle, the sector normals at its corners (floats: the guard compares
  // them with a 30 degree limit), each computed once; the guard asks for each many times.
  Chunked<std::array<float, 9>> corner_normal_;

  std::array<std::deque<FaceId>, 9> queue_;
  std::size_t refined_count_ = 0;
  std::uint64_t max_faces_ = 0;
  const std::atomic<bool>* cancel_ = nullptr;
  const std::atomic<bool>* scope_cancel_ = nullptr;  // the CancelScope run() was called in
  Sqrt3AdaptiveStats stats_;
  std::function<void(std::uint64_t)> reserve_;
  std::uint64_t patch_bytes_ = 0;      // the stencil patches alive at once, at most
  std::uint64_t transient_bytes_ = 0;  // a work array alive now besides the hierarchy
};

}  // namespace stlrefine
