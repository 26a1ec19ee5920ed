// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/analysis/local_matrix.h"

#include <cmath>
#include <numbers>
#include <string>

#include "core/error.h"
#include "core/schemes/sqrt3_host.h"

namespace stlrefine::analysis {

namespace {

// Values ride in z, scaled by a power of two (exact for linear stencils). Geometry stays
// the planar net in x and y, so a stencil that reads the geometry (LSF) is linearised
// about the flat net: its weights move by O(eps^2) only.
constexpr double kEps = 1.0 / (1 << 30);

// Rings of margin around the analysed net: far enough that boundary rules never reach in.
constexpr int kMargin = 2;

[[noreturn]] void fail(const std::string& what) {
  throw Error(ErrorCode::Internal, "spectral_analysis", "spectral analysis: " + what);
}

}  // namespace

Refiner Refiner::of(const Scheme& scheme) {
  if (const auto* s = dynamic_cast<const HostScheme<Split4Stencil>*>(&scheme))
    return of(s->stencil());
  if (const auto* s = dynamic_cast<const HostScheme<Sqrt3Stencil>*>(&scheme)) {
    Refiner r;
    r.scale_ = 3;
    // Without the fold guard: the stencil's linear rules alone (as split4 below).
    r.step_ = [s](const Level& coarse) {
      StepStats stats;
      const Sqrt3Stencil& stencil = s->stencil();
      return sqrt3_refine(sqrt3_refine(coarse, stencil, stats, FoldGuard::Off), stencil, stats,
                          FoldGuard::Off);
    };
    return r;
  }
  fail("no analysis host for scheme " + std::string(scheme.name()));
}

Refiner Refiner::of(const Split4Stencil& stencil) {
  Refiner r;
  r.scale_ = 2;
  r.step_ = [&stencil](const Level& coarse) {
    StepStats stats;
    return split4(coarse, stencil, stats, FoldGuard::Off);
  };
  return r;
}

NetLevel make_net_level(int valence, int rings, int margin) {
  PolarNet net = make_polar_net(valence, rings + margin);
  NetLevel out;
  out.ids.assign(net.ids.begin(), net.ids.begin() + PolarLayout{valence, rings}.size());
  BigVector<std::uint8_t> smooth(net.mesh.num_edges(), 0);
  out.level.features = Features(net.mesh, std::move(smooth));  // only the outer ring is sharp
  out.level.mesh = std::move(net.mesh);
  out.level.step = kStationaryStep;
  return out;
}

std::vector<VertexId> fine_polar_ids(const Mesh& fine, int rings) {
  // Old vertices keep their ids in both hosts: the centre is vertex 0. By symmetry the
  // fine spoke 0 lies exactly on the +x axis (a split4 edge point of coarse spoke 0, or
  // the sqrt3 point at 1/3 of it).
  const VertexId centre(0);
  const Vec3 c = fine.position(centre);
  HalfedgeId best;
  double best_cos = -2;
  for_each_outgoing(fine, centre, [&](HalfedgeId h) {
    const Vec3 d = fine.position(fine.to(h)) - c;
    const double len = std::sqrt(dot(d, d));
    const double cosine = len > 0 ? d.x / len : -2;
    if (cosine > best_cos) best_cos = cosine, best = h;
  });
  if (!best.valid() || best_cos < 1 - 1e-9) fail("no fine spoke along the coarse spoke 0");
  std::vector<VertexId> ids = walk_polar_net(fine, best, rings);
  if (ids.empty()) fail("the refined net is not a polar net");
  return ids;
}

namespace {

// One analysis step of `net` with z = eps * values on the given coarse vertices (all other
// z from `outside`), read back as z / eps at the fine ids.
Eigen::VectorXd run_column(const Refiner& refine, const NetLevel& net,
                           const std::vector<VertexId>& fine_ids,
                           const std::vector<std::pair<VertexId, double>>& values,
                           double outside = 0) {
  Level level = net.level;
  BigVector<Vec3>& pos = level.mesh.mutable_positions();
  if (outside != 0)
    for (std::uint32_t v = 0; v < pos.size(); ++v) pos[v].z = outside * probe_value(VertexId(v));
  for (VertexId v : net.ids) pos[v.idx].z = 0;
  for (const auto& [v, x] : values) pos[v.idx].z = kEps * x;
  const Level fine = refine(level);
  Eigen::VectorXd out(fine_ids.size());
  for (std::size_t i = 0; i < fine_ids.size(); ++i)
    out[static_cast<Eigen::Index>(i)] = fine.mesh.position(fine_ids[i]).z / kEps;
  return out;
}

// How many fine rings one step determines from the coarse net of `rings` rings alone:
// the largest r such that moving every coarse vertex outside the net leaves every fine
// vertex of rings <= r exactly where it was. >= rings: the net is closed; > rings: it also
// determines a first surface ring (r1 > r0 in PU section 4).
int determined_rings(const Refiner& refine, int valence, int rings, NetLevel& net) {
  net = make_net_level(valence, rings, kMargin);
  const int deepest = rings * refine.scale();
  const std::vector<VertexId> ids = fine_polar_ids(refine(net.level).mesh, deepest);
  const Eigen::VectorXd probe = run_column(refine, net, ids, {}, 1.0);
  const PolarLayout fine{valence, deepest};
  int r = 0;
  for (; r < deepest; ++r) {
    bool untouched = true;
    for (int b = 0; b <= r && untouched; ++b)
      for (int k = 0; k < valence && untouched; ++k)
        untouched = probe[fine.index(PolarLayout::position(r + 1 - b, b), k)] == 0.0;
    if (!untouched) break;
  }
  return r;
}

}  // namespace

LocalMatrix local_subdivision_matrix(const Refiner& refine, int n, const LocalMatrixOptions& o) {
  if (n < 3) fail("valence below 3");
  NetLevel net;
  int rings = o.rings;
  if (rings > 0) {
    if (determined_rings(refine, n, rings, net) < rings)
      fail(std::to_string(rings) + " rings are not closed under one step");
  } else {
    for (rings = 1; determined_rings(refine, n, rings, net) <= rings; ++rings)
      if (rings == 6) fail("no net up to 6 rings determines a surface ring");
  }
  const std::vector<VertexId> fine_ids = fine_polar_ids(refine(net.level).mesh, rings);
  const PolarLayout lay{n, rings};
  const int size = lay.size();
  LocalMatrix out{lay, refine.scale(), Eigen::MatrixXd::Zero(size, size)};
  Eigen::MatrixXd& a = out.a;
  if (!o.use_symmetry) {
    for (int j = 0; j < size; ++j) a.col(j) = run_column(refine, net, fine_ids, {{net.ids[j], 1}});
    return out;
  }
  // A commutes with the rotation by one sector: A[(p, j), (q, k)] = A[(p, j - k), (q, 0)],
  // and the centre row is the same for every sector.
  a.col(0) = run_column(refine, net, fine_ids, {{net.ids[0], 1}});
  for (int q = 0; q < lay.positions(); ++q) {
    const Eigen::VectorXd col = run_column(refine, net, fine_ids, {{net.ids[lay.index(q, 0)], 1}});
    for (int k = 0; k < n; ++k) {
      a(0, lay.index(q, k)) = col[0];
      for (int p = 0; p < lay.positions(); ++p)
        for (int j = 0; j < n; ++j) a(lay.index(p, j), lay.index(q, k)) = col[lay.index(p, j - k)];
    }
  }
  return out;
}

Eigen::MatrixXd curve_subdivision_matrix(const Refiner& refine, int half_width) {
  // A strip of equilateral triangles, rows j = 0..3, its lower edge the curve:
  //   (i,j+1) --- (i+1,j+1)      up:   (i,j), (i+1,j), (i,j+1)
  //      \  down  /   \          down: (i+1,j), (i+1,j+1), (i,j+1)
  //      (i,j) --- (i+1,j)       boundary vertices have valence 4 (regular crease vertices)
  const int margin = 6, rows = 4;
  const int nx = 2 * (half_width + margin);
  const int centre = half_width + margin;
  auto vid = [&](int i, int j) { return VertexId(static_cast<std::uint32_t>(j * (nx + 1) + i)); };
  BigVector<Vec3> pos((nx + 1) * (rows + 1));
  for (int j = 0; j <= rows; ++j)
    for (int i = 0; i <= nx; ++i) pos[vid(i, j).idx] = {i + 0.5 * j, j * std::sqrt(3.0) / 2, 0};
  BigVector<VertexId> corners;
  for (int j = 0; j < rows; ++j) {
    for (int i = 0; i < nx; ++i) {
      for (VertexId v : {vid(i, j), vid(i + 1, j), vid(i, j + 1)}) corners.push_back(v);
      for (VertexId v : {vid(i + 1, j), vid(i + 1, j + 1), vid(i, j + 1)}) corners.push_back(v);
    }
  }
  Level coarse;
  coarse.mesh = mesh_from_triangles(std::move(pos), std::move(corners));
  coarse.features = Features(coarse.mesh, BigVector<std::uint8_t>(coarse.mesh.num_edges(), 0));
  coarse.step = kStationaryStep;

  const int size = 2 * half_width + 1;
  std::vector<VertexId> coarse_ids(size), fine_ids(size);
  for (int t = 0; t < size; ++t) coarse_ids[t] = vid(centre - half_width + t, 0);
  // Along the fine curve from the centre (an old vertex, same id) both ways, +x first.
  {
    const Level geometry = refine(coarse);
    const Features& f = geometry.features;
    const VertexId c = coarse_ids[half_width];
    fine_ids[half_width] = c;
    for (int side : {+1, -1}) {
      const auto& ends = f.curve_neighbours(c);
      if (!ends[0].valid() || !ends[1].valid()) fail("the curve centre is not a crease vertex");
      const double x0 = geometry.mesh.position(ends[0]).x;
      const double x1 = geometry.mesh.position(ends[1]).x;
      VertexId prev = c, here = (x0 > x1) == (side > 0) ? ends[0] : ends[1];
      for (int t = 1; t <= half_width; ++t) {
        fine_ids[half_width + side * t] = here;
        const VertexId next = f.curve_beyond(here, prev);
        prev = here, here = next;
        if (t < half_width && !here.valid()) fail("the fine curve ends too early");
      }
    }
  }
  auto column = [&](int j, double outside) {
    Level level = coarse;
    BigVector<Vec3>& p = level.mesh.mutable_positions();
    for (std::uint32_t v = 0; v < p.size(); ++v) p[v].z = outside * probe_value(VertexId(v));
    for (VertexId v : coarse_ids) p[v.idx].z = 0;
    if (j >= 0) p[coarse_ids[j].idx].z = kEps;
    const Level fine = refine(level);
    Eigen::VectorXd out(size);
    for (int i = 0; i < size; ++i) out[i] = fine.mesh.position(fine_ids[i]).z / kEps;
    return out;
  };
  if (column(-1, 1.0).cwiseAbs().maxCoeff() != 0.0)
    fail("the curve rule reads more than the curve window");
  Eigen::MatrixXd s(size, size);
  for (int j = 0; j < size; ++j) s.col(j) = column(j, 0);
  return s;
}

}  // namespace stlrefine::analysis
