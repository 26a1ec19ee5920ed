// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// The adaptive sqrt3 output: the conforming mesh of the triangles that exist, built in
// phases that memory admission reserves one by one; and AdaptiveSqrt3's own members.
#include <algorithm>
#include <array>
#include <limits>
#include <utility>
#include <vector>

#include "core/refine.h"
#include "core/schemes/adaptive_sqrt3_hierarchy.h"

namespace stlrefine {

using namespace adaptive_sqrt3_detail;

namespace {
constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
}  // namespace

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
  using Face = std::array<VertexId, 3>;
  const std::uint64_t face_list = num_faces * sizeof(Face);
  const std::uint64_t face_bits = 2 * std::uint64_t(num_faces);  // sharp bits, levels
  phase(face_list + face_bits);

  stats_.flips_kept = 0;
  stats_.face_points_pulled = 0;
  std::vector<Face> faces;
  std::vector<std::uint8_t> sharp_bits, levels;
  faces.reserve(num_faces);
  sharp_bits.reserve(num_faces);
  levels.reserve(num_faces);
  for (std::uint32_t i = 0; i < tris_.size(); ++i) {
    const FaceId t(i);
    if (!exists(t)) continue;
    const int l = level(t);
    if (!refined(t)) {
      faces.push_back(tris_[t].v);
      sharp_bits.push_back(tris_[t].sharp);
      levels.push_back(static_cast<std::uint8_t>(l));
      continue;
    }
    // An edge both of whose sides are refined and that the fold guard kept, counted once.
    for (std::uint8_t k = 0; k < 3; ++k) {
      if (!((tris_[t].keep >> (3 + k)) & 1)) continue;
      const HalfedgeId tw = twin(he(t, k));
      if (refined(Mesh::face(tw)) && he(t, k).idx < tw.idx) ++stats_.flips_kept;
    }
    // Where the old edge is not flipped yet: the split's piece (from, to, apex).
    const HalfedgeId s = trisects(l) ? sharp_of(t) : HalfedgeId();
    for (std::uint8_t k = 0; k < 3; ++k) {
      const HalfedgeId h = he(t, k);
      if (!makes_flip_child(h) || refined(Mesh::face(twin(h)))) continue;
      faces.push_back({from(h), to(h), apex(h)});
      std::uint8_t bits = sharp(h) ? 1 : 0;
      if (s.valid() && h == Mesh::prev(s)) bits |= 2;  // to(h) -> m1: the first third of s
      if (s.valid() && h == Mesh::next(s)) bits |= 4;  // m2 -> from(h): the last third of s
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
    for (VertexId v : faces[f]) vertex_level[v.idx] = std::max(vertex_level[v.idx], levels[f]);
  std::size_t nu = input_vertices_;
  for (const Face& f : faces)
    for (VertexId v : f)
      if (out_id[v.idx] == kNone) out_id[v.idx] = 0, ++nu;
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
    positions[i] = position(VertexId(used[i]), vertex_level[used[i]]);
    stats_.face_points_pulled += verts_[VertexId(used[i])].pulled;
    if (has_alpha_) alpha[i] = alpha_[used[i]];
  }
  std::vector<std::uint32_t>().swap(used);
  std::vector<std::uint8_t>().swap(vertex_level);

  const std::uint64_t corners = big_vector_bytes<VertexId>(nh);
  phase(face_list + face_bits + nv * sizeof(std::uint32_t) + vertex_arrays + corners);
  BigVector<VertexId> corner(nh);
  for (std::size_t f = 0; f < faces.size(); ++f)
    for (std::size_t k = 0; k < 3; ++k) corner[3 * f + k] = VertexId(out_id[faces[f][k].idx]);
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
