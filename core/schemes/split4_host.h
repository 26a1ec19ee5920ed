// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <cstdint>
#include <functional>
#include <span>

#include "core/schemes/host_scheme.h"
#include "core/schemes/scheme.h"

namespace stlrefine {

//! The geometric rules of a 1-to-4 scheme: where new edge points go and, for
//! approximating schemes, where old vertices move. Reads the coarse level only.
class Split4Stencil {
 public:
  virtual ~Split4Stencil() = default;
  //! Writes one point per coarse edge, indexed by EdgeId.
  virtual void edge_points(const Level& coarse, std::span<Vec3> out) const = 0;
  //! Writes one point per coarse vertex. Interpolating stencils keep the default (copy).
  virtual void vertex_points(const Level& coarse, std::span<Vec3> out) const;
  virtual bool interpolating() const = 0;
  //! Whether the host runs its fold guard after this stencil: interpolating stencils by
  //! default; butterfly-g1 (which moves a few later-level vertices) asks for it too.
  virtual bool guards_folds() const { return interpolating(); }
  //! Whether this stencil checks its smooth edge points against the Hermite midpoints of the
  //! surface's normals (check_edge_points_against_normals, within the default scratch_bytes).
  virtual bool checks_against_normals() const { return false; }
  //! Whether points() reads the level's irregular vertices (the spectral stencils): the
  //! host then finds them once and carries them to the next level.
  virtual bool uses_irregular() const { return false; }
  //! Vertex and edge points together, the host's entry point. `irregular` is valid for
  //! the coarse mesh when uses_irregular(), else empty. Default: vertex_points, edge_points.
  virtual void points(const Level& coarse, const IrregularVertices& irregular,
                      std::span<Vec3> vertex_out, std::span<Vec3> edge_out) const;
  //! Heap bytes points() allocates besides its output, at most (memory admission, see
  //! MemoryGrowFn in core/refine.h). The default, 24 B per edge and 64 per vertex, bounds
  //! the built-in stencils: lsf's second estimate per edge, butterfly's valence per vertex,
  //! the spectral stencils' candidates and polar nets (sites lie clean rings apart);
  //! per-thread ring buffers are in the refinement's fixed slack.
  virtual std::uint64_t scratch_bytes(const Level& coarse) const;
};

//! level.irregular when it is valid for level.mesh, else found now (one pass over the
//! vertices).
IrregularVertices irregular_vertices(const Level& level);

//! The fold guard's limit (degrees): no child face turns further than this from the smooth
//! normals of the surface the coarse mesh stands for (issue 17 item 2).
inline constexpr double kFoldAngleDeg = 60.0;

//! The angle (degrees) the guard holds each child to, from the smooth normals it has: those
//! are estimates (the input's sector normals, carried), up to about 15 degrees from the true
//! normals on the generated CAD-like families, so the guard keeps that margin below
//! kFoldAngleDeg.
inline constexpr double kGuardAngleDeg = kFoldAngleDeg - 15.0;

//! 1-to-4 split (Loop / butterfly / LSF topology). New vertex ids: old vertices keep
//! theirs, then one per coarse edge (V + e). Face 4f+k is the corner triangle at corner
//! k of coarse face f, 4f+3 the middle one. Halves of sharp edges stay sharp.
//! For interpolating stencils the fold guard runs: an edge point whose child faces would
//! turn more than kGuardAngleDeg from the smooth normals (coarse.smooth_normals when it
//! holds them, else sector_normals; see guard_folds) or more than 90 degrees from their
//! parent is moved back towards its chord midpoint; the fine level carries the smooth
//! normals on (split4_smooth_normals).
Level split4(const Level& coarse, const Split4Stencil& stencil, StepStats& stats,
             FoldGuard guard = FoldGuard::AsStencil);

//! Per corner of a face (indexed by the half-edge leaving the corner's vertex): the unit
//! angle-weighted mean of the face normals around that vertex within the corner's crease
//! sector (bounded by sharp edges), the smooth surface's normal there as the coarse mesh
//! tells it. Zero on a sector of zero-area faces.
BigVector<Vec3> sector_normals(const Mesh& coarse, const Features& features);

//! The fold guard on its own: `positions` holds the coarse vertices then one edge point
//! per coarse edge (V + e). Pulls edge points whose 1-to-4 children would turn more than
//! kGuardAngleDeg from the smooth normals (the sector normals at the child's old vertices,
//! their edge means at its new ones) or more than 90 degrees from their parent towards the
//! chord midpoint, smooth edges before sharp ones; an old vertex the stencil moved
//! (butterfly-g1) of such a child goes back towards its coarse position first. Returns how
//! many edge points and vertices moved. It allocates a
//! byte per edge and per face and guard_folds_normal_bytes; only when some child folds,
//! guard_folds_work_bytes more, and calls `reserve` with that first.
std::size_t guard_folds(const Mesh& coarse, const Features& features, BigVector<Vec3>& positions,
                        const std::function<void(std::uint64_t)>& reserve = {});

//! guard_folds with the smooth normals given per corner of a coarse face (as
//! sector_normals gives them, or as carried by Level::smooth_normals).
std::size_t guard_folds(const Mesh& coarse, const Features& features,
                        const BigVector<Vec3>& corner_normals, BigVector<Vec3>& positions,
                        const std::function<void(std::uint64_t)>& reserve = {});

//! The smooth normals of the fine level's face corners (Level::smooth_normals) from the
//! coarse level's: an old vertex keeps its corner's normal, an edge point gets the unit mean
//! of its edge's two corner normals in the face (the guard's estimate there).
BigVector<Vec3> split4_smooth_normals(const Mesh& coarse, const BigVector<Vec3>& corner_normals);

//! Plane rule (issue 17 items 2 and 6), run before the fold guard: an edge point of a
//! smooth interior edge goes onto the plane of one of its faces when that plane dominates
//! both endpoints: its faces (coplanar to the rounding of their coordinates) hold at least
//! half of the face area of the endpoint's crease sector, and its largest face there is at
//! least twice as large as any face off it. A CAD part's flat face, two big triangles or a
//! fan beside the thin strips of a tangent fillet, then stays flat instead of taking the
//! stencil's bulge from the fillet's vertices. Where every stencil point lies on the plane
//! the stencil's point is on it already and nothing moves. Returns how many moved.
std::size_t keep_dominant_planes(const Mesh& coarse, const Features& features,
                                 BigVector<Vec3>& positions);

//! The check of smooth edge points against the surface's normals (issue 17 item 3).
struct NormalCheckParams {
  //! How far (in the normal direction) an edge point may be from the Hermite midpoint of its
  //! edge, as a fraction of that midpoint's own offset from the chord, [0, 4].
  double slack = 0.25;
  //! Plus this fraction of the narrower face's height across the edge, [0, 0.1]: what the
  //! normals cannot resolve.
  double width_fraction = 1e-3;
  //! Only edges with an end whose longest spoke is at least this many times its shortest are
  //! checked, [1, 1000]: the butterfly's lattice weights are the paper's elsewhere. 3 is lsf's
  //! kEvenSpokes (a fan or a zipper).
  double uneven_spokes = 3.0;
  //! The normals are trusted for at most this many times the bulge of an arc across the
  //! wider face's height turning by the angle between them, [1, 1000]: on a sliver the
  //! normals cannot tell whether they turn along its length (curvature the Hermite midpoint
  //! follows) or at one end (a kink the vertex normal averages over, as on a flat wall
  //! meeting another at a few degrees). Past it, a point between the chord and the Hermite
  //! midpoint is kept.
  double sliver_trust = 2.0;
  //! That bound holds for end normals less than this many degrees apart, [0, 180] (0: never):
  //! a kink a vertex normal averages over stays below the crease angle; a larger turn (a rim
  //! left smooth, 45 degrees and more) is the surface's.
  double sliver_turn_deg = 10.0;
  //! \throw std::invalid_argument when a value is outside its range.
  void validate() const;
};

//! Per vertex: 1 where its longest spoke is at least `ratio` times its shortest (a fan, a
//! zipper, a sliver's end, a hull's uneven ring), where lattice weights do not hold; 0 for
//! isolated vertices. The normal checks of split4 and sqrt3 start from it.
std::vector<std::uint8_t> uneven_spoke_vertices(const Mesh& m, double ratio);

//! Normal check (issue 17 item 3), ours: the butterfly stencils run it on their edge points
//! (indexed by EdgeId), so every host (split4, the adaptive ones) has it before its plane rule
//! and fold guard. The butterfly's weights assume a lattice; on CAD tessellations (fans,
//! zipped slivers, hull rings of uneven spokes) its point is off the surface by about the
//! input's own chordal error, and the fold guard's flat midpoint keeps that error. So at a
//! smooth interior edge a-b with an uneven end (NormalCheckParams::uneven_spokes) the point
//! becomes the edge's Hermite midpoint H (hermite_midpoint_offset from lsf's guard normals at
//! a and b on this level: exact on circular arcs) when its offset from the chord midpoint
//! along their mean normal is farther from H's than slack |H - mid| + width_fraction (the
//! narrower face's height). Where H bulges more than the normals can be trusted for across
//! the strip (sliver_trust), H is only a bound: a point between the chord and H stays, one
//! beyond goes to H, one behind the chord to the chord's midpoint. On a plane H is the
//! midpoint and the stencil's point is on the plane: nothing moves. Returns how many moved.
std::size_t check_edge_points_against_normals(const Mesh& coarse, const Features& features,
                                              std::span<Vec3> edge_points,
                                              const NormalCheckParams& params = {});

//! What check_edge_points_against_normals allocates (a flag per vertex and per edge).
std::uint64_t check_edge_points_bytes(const Mesh& coarse);

//! What keep_dominant_planes allocates (a plane per face, a flag per corner and per edge).
std::uint64_t keep_dominant_planes_bytes(const Mesh& coarse);

//! The fold guard's smooth normals (three per face), always allocated.
std::uint64_t guard_folds_normal_bytes(const Mesh& coarse);

//! The fold guard's work arrays when some child folds: the original edge points, two face
//! lists, and a stage and the stencil's point per vertex (for vertices the stencil moved).
std::uint64_t guard_folds_work_bytes(const Mesh& coarse);

//! Heap bytes split4(coarse, stencil) allocates at most, the fine level included.
std::uint64_t split4_step_bytes(const Level& coarse, const Split4Stencil& stencil);

//! The 1-to-4 host of HostScheme<Split4Stencil> (host_scheme.h).
template <>
struct Host<Split4Stencil> {
  static constexpr unsigned kFacesPerFace = 4;
  static Level step(const Level& coarse, const Split4Stencil& stencil, StepStats& stats) {
    return split4(coarse, stencil, stats);
  }
};

}  // namespace stlrefine
