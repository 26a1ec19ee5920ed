// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <unordered_map>
#include <vector>

#include "core/schemes/split4_host.h"

namespace stlrefine {

//! What one adaptive step did.
struct AdaptiveStepStats {
  std::size_t marked_by_tolerance = 0;  //!< edges over tol (or the dihedral angle)
  std::size_t red_by_tolerance = 0;     //!< faces split 1-to-4 because an edge was over tol
  std::size_t red_by_closure = 0;       //!< faces split 1-to-4 to keep the mesh 1-irregular
  std::size_t red_faces = 0;            //!< red_by_tolerance + red_by_closure
  std::size_t green_faces = 0;          //!< faces of the result bisected to close a hanging node
};

//! Edges of `level` whose edge point (the stencil's on `level` itself, after the fold
//! guard; AdaptiveSplit4::remaining() measures the adaptive hierarchy) lies more than
//! `tolerance` from the edge's chord midpoint (spec 5 gap 4), or, when angle_deg > 0,
//! non-sharp edges whose two faces' normals differ by more than angle_deg. A criterion is
//! off when it is 0.
//! `reserve`, when set, is called first with the bytes it allocates at most.
std::size_t count_edges_over_tolerance(const Level& level, const Split4Stencil& stencil,
                                       double tolerance, double angle_deg = 0,
                                       const std::function<void(std::uint64_t)>& reserve = {});

//! The edges count_edges_over_tolerance counts, and the worst of them: the largest distance
//! of an edge point from its chord midpoint among them (0 when only the angle marks them),
//! and that edge's chord midpoint.
struct EdgesOverTolerance {
  std::size_t count = 0;
  double max_distance = 0;
  Vec3 worst_at{0, 0, 0};
  //! AdaptiveSplit4::remaining() only: of `count`, the halves of a split edge whose point
  //! leaves the chord by more than half as far as the split edge's midpoint left its chord
  //! (a converging scheme shrinks it about four times per level).
  std::size_t not_shrinking = 0;
};
EdgesOverTolerance edges_over_tolerance(const Level& level, const Split4Stencil& stencil,
                                        double tolerance, double angle_deg = 0,
                                        const std::function<void(std::uint64_t)>& reserve = {});

//! Curvature-adaptive 1-to-4 refinement with red-green closure (spec 5 gap 4).
//!
//! The state is a hierarchy of red (1-to-4) triangles that is 1-irregular: an edge carries
//! at most one hanging midpoint. The conforming mesh `level()` bisects each triangle with a
//! hanging midpoint (green); greens are never refined themselves: when a green pair needs
//! refinement its parent is split red instead, so repeated steps do not make slivers.
//! Every red leaf of level k is a face of the uniform level k. A step splits red every leaf
//! with an edge whose edge point leaves the chord by more than the tolerance, then closes:
//! a triangle that would get two hanging midpoints, or a midpoint on a half of its own
//! split edge, is split red too. Vertices are never moved or renumbered (the schemes are
//! interpolating), so input vertex v is output vertex v; watertight in, watertight out.
//!
//! Edge points (issue 17): on a simple mesh (require_simple_mesh) a leaf's edges are
//! measured and split with the points uniform refinement puts there, the stencil and the
//! fold guard evaluated on a region of the uniform level (the faces the hierarchy split
//! plus kRegionMargin rings, made by split4 from the level below), and only where the
//! region's cut and every point not known to be uniform are kStencilReach edges or more
//! away (else Error(Internal, "adaptive_stencil_margin")). So a split leaf has the children
//! uniform refinement gives it, the measure of an edge does not depend on the tolerance,
//! and a smaller tolerance splits a superset of the leaves. The stencil is not evaluated on
//! the conforming mesh, whose green triangles and mixed levels it is not made for (there
//! butterfly's points left their chords by more at each level and never converged).
//!
//! Edges are known by identity (the input's EdgeIds, then one entry per half and per inner
//! edge of a split), so meshes that are not simple work as they do in uniform refinement:
//! two edges between the same two vertices (ingest cuts a non-manifold edge apart that way)
//! and a facet with its reverse (a two-face pillow). On those the uniform regions (which
//! know edges by their end vertices) are not used: the points come from the stencil on the
//! conforming mesh, as before issue 17, without the guarantees above.
//!
//! Memory: `reserve`, when set, is called with the bytes this object will hold at most
//! until its next call (its arrays, the conforming level, and the work arrays of the phase
//! about to run), before they are allocated; it throws to stop the refinement. A step
//! reserves its marking phase, then, once the next level's exact size is known and within
//! max_faces, its commit and build: a level over max_faces is never reserved.
class AdaptiveSplit4 {
 public:
  explicit AdaptiveSplit4(const Level& coarse,
                          std::function<void(std::uint64_t bytes)> reserve = {});

  //! One step. Returns false, changing nothing, when no edge is over a criterion (see
  //! count_edges_over_tolerance).
  //! \throw Error(BudgetExceeded, field "max_faces") as soon as the next level is known to
  //! pass max_faces (a lower bound right after the marking, else the exact count), before
  //! anything of it is built.
  bool step(const Split4Stencil& stencil, double tolerance, std::uint64_t max_faces,
            StepStats& stats, AdaptiveStepStats& step, double angle_deg = 0);

  //! Bytes of the arrays this object holds now, the conforming level included.
  std::uint64_t held_bytes() const;

  //! The leaf edges a step would still find over a criterion now (count, worst distance
  //! and where), measured as step() measures them.
  EdgesOverTolerance remaining(const Split4Stencil& stencil, double tolerance,
                               double angle_deg = 0);

  //! Whether edge points come from the uniform levels (simple meshes: no two edges join
  //! the same two vertices) rather than from the conforming mesh.
  bool uniform_points() const { return uniform_points_; }

  //! The current conforming mesh and its features.
  const Level& level() const { return level_; }
  Level release() { return std::move(level_); }

 private:
  static constexpr std::uint32_t kNone = 0xffffffffu;
  struct Edge {
    std::array<std::uint32_t, 2> v;                   // end vertices
    std::uint32_t mid = kNone;                        // midpoint vertex once split
    std::array<std::uint32_t, 2> half{kNone, kNone};  // edges v[0]-mid and mid-v[1]
    std::uint32_t parent = kNone;                     // the edge this one is a half of
    bool sharp = false;
  };
  struct Leaf {
    std::array<std::uint32_t, 3> v;  // corners, oriented like the input
    std::array<std::uint32_t, 3> e;  // e[k] joins v[k] and v[k+1]
    std::uint32_t level = 0;         // a face of the uniform level `level`
  };
  //! A region of the uniform level k (every leaf of level k lies inside it, with a margin),
  //! made by the stencil's own 1-to-4 step from a region of level k - 1, so its points are
  //! bit for bit those of uniform refinement wherever the region's cut is farther than the
  //! stencil reaches.
  struct UniformLevel {
    Level level;
    std::vector<std::uint32_t> hierarchy_vertex;  // per vertex: positions_ index, or kNone
    std::vector<std::uint8_t> trusted;            // per vertex: the uniform level's position
    std::vector<std::uint8_t> cut;                // per edge: a boundary made by the cut
    BigVector<Vec3> points;                       // vertex points then edge points (V + e)
    std::vector<std::uint8_t> edge_trusted;       // per edge: its point is the uniform one
    std::vector<std::uint8_t> edge_guarded;       // per edge: the fold guard moved its point
    std::unordered_map<std::uint64_t, std::uint32_t> edge_of;  // vertex pair -> edge
    std::size_t source_split = 0;  // faces of level k - 1 split when it was made
  };
  //! Rebuilds uniform_[1..K] for the leaves' finest level K (uniform_[0] is the input).
  void update_uniform(const Split4Stencil& stencil);
  void evaluate_uniform(UniformLevel& u, const Split4Stencil& stencil);
  //! Per leaf edge of level k: its uniform edge point; throws when the margin fell short.
  Vec3 uniform_point(std::uint32_t leaf, std::uint32_t k, bool* guarded = nullptr) const;
  //! Whether leaf edge k of `leaf` is over a criterion (uniform points); `dist` its distance.
  bool uniform_over(std::uint32_t leaf, std::uint32_t k, double tolerance, double cos_limit,
                    bool angle_on, double& dist) const;
  std::uint64_t uniform_bytes() const;
  //! Whether bisecting `leaf` at point p of its side k (the green closure) turns a half
  //! more than kGreenTurnDeg from the leaf: a sliver whose split side bulges towards its
  //! opposite corner would fold, so the closure splits it red instead.
  bool green_turns(std::uint32_t leaf, std::uint32_t k, const Vec3& p) const;
  static std::uint64_t pair_key(std::uint32_t a, std::uint32_t b) {
    return a < b ? (std::uint64_t(a) << 32 | b) : (std::uint64_t(b) << 32 | a);
  }
  void build_level();
  //! What build_level() allocates at most for a hierarchy of `leaves` leaves (`greens` of
  //! them green), `edges` edges and `vertices` vertices, whose conforming mesh has `faces`.
  std::uint64_t build_bytes(std::uint64_t faces, std::uint64_t greens, std::uint64_t leaves,
                            std::uint64_t edges, std::uint64_t vertices) const;
  void need(std::uint64_t bytes) const {
    if (reserve_) reserve_(bytes);
  }
  //! The half of split edge e that ends at vertex x.
  std::uint32_t half_at(std::uint32_t e, std::uint32_t x) const {
    return edges_[e].v[0] == x ? edges_[e].half[0] : edges_[e].half[1];
  }
  std::uint32_t add_edge(std::uint32_t a, std::uint32_t b, bool sharp, std::uint32_t parent);

  std::vector<Vec3> positions_;
  std::vector<Edge> edges_;
  std::vector<Leaf> leaves_;  // the hierarchy's leaves
  Level level_;
  // For each face of level_: the leaf it belongs to; for each leaf edge k the half-edge of
  // level_ that is that edge, or invalid when the edge is split by a hanging midpoint.
  std::vector<std::uint32_t> owner_;
  std::vector<std::array<HalfedgeId, 3>> leaf_halfedge_;
  std::function<void(std::uint64_t)> reserve_;
  bool uniform_points_ = false;
  std::vector<UniformLevel> uniform_;
};

}  // namespace stlrefine
