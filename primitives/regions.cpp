// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "primitives/regions.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "primitives/chordal.h"

namespace stlrefine::primitives {

namespace {

struct Patch {
  std::vector<std::uint32_t> faces;
  std::vector<Vec3> points;  // its distinct vertices
  std::vector<Vec3> normals, centroids;
  double area = 0;
};

Patch make_patch(const Mesh& mesh, const std::vector<std::uint32_t>& faces,
                 std::vector<std::uint32_t>& stamp, std::uint32_t mark) {
  Patch p;
  p.faces = faces;
  for (std::uint32_t f : faces) {
    const auto vs = mesh.face_vertices(FaceId(f));
    for (VertexId v : vs) {
      if (stamp[v.idx] == mark) continue;
      stamp[v.idx] = mark;
      p.points.push_back(mesh.position(v));
    }
    const Vec3 n = mesh.face_normal(FaceId(f));
    const double len = norm(n);
    p.area += len / 2;
    if (len > 0) {
      p.normals.push_back(n * (1.0 / len));
      p.centroids.push_back((mesh.position(vs[0]) + mesh.position(vs[1]) + mesh.position(vs[2])) *
                            (1.0 / 3));
    }
  }
  return p;
}

// chordal_bounds is an estimate from the input's normals: on the generated CAD-like families
// (seeds 1-10) the true surface was at most 1.22 times it from a face (8 faces of 28,506
// off the truth by more than 1e-9 of the diagonal were over it; PrimitivesMeasure.
// DISABLED_ChordalBoundCoverage, bench/results-issue17-primitives.md). A fit farther than twice it
// from a face's chords is not the surface the face was cut from.
constexpr double kChordSlack = 2;

std::size_t min_curved_vertices(PrimitiveType type) {
  switch (type) {
    case PrimitiveType::Sphere:
    case PrimitiveType::Cylinder:
      return 12;
    case PrimitiveType::Cone:
      return 14;
    case PrimitiveType::Torus:
      return 18;
    case PrimitiveType::Plane:
      break;
  }
  return 3;
}

double max_residual(const Primitive& prim, const std::vector<Vec3>& points) {
  double worst = 0;
  for (const Vec3& p : points) worst = std::max(worst, prim.distance(p));
  return worst;
}

// A curved fit of a large patch, tried first on an evenly strided sample of its points,
// normals and centroids (kSample each): a surface every vertex lies on is found from a
// sample of them, and a patch no primitive fits (a freeform region of thousands of faces)
// is then refused after one cheap fit whose residual over all points is far off, instead of
// a Levenberg-Marquardt fit over every point for each type.
constexpr std::size_t kSample = 64;

std::vector<Vec3> strided(const std::vector<Vec3>& v) {
  if (v.size() <= kSample) return v;
  std::vector<Vec3> out;
  out.reserve(kSample);
  for (std::size_t i = 0; i < kSample; ++i) out.push_back(v[i * v.size() / kSample]);
  return out;
}

std::optional<Primitive> fit_curved(PrimitiveType type, const Patch& patch, double tol) {
  if (patch.points.size() > 2 * kSample) {
    const std::optional<Primitive> quick = fit_primitive(
        type, strided(patch.points), strided(patch.normals), strided(patch.centroids));
    if (!quick) return std::nullopt;
    if (max_residual(*quick, patch.points) <= tol) return quick;
    // Far off (a hundred tolerances): no refit over every point will fit.
    if (max_residual(*quick, patch.points) > 100 * tol) return std::nullopt;
  }
  return fit_primitive(type, patch.points, patch.normals, patch.centroids);
}

}  // namespace

RegionMap detect_regions(const Mesh& mesh, const Features& features, const RegionParams& params) {
  RegionMap out;
  const std::size_t nf = mesh.num_faces();
  out.face_region.assign(nf, -1);
  if (nf == 0) return out;
  Vec3 lo = mesh.position(VertexId(0)), hi = lo;
  for (const Vec3& p : mesh.positions()) {
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
  }
  out.bbox_diagonal = distance(lo, hi);
  out.tolerance = params.tolerance * out.bbox_diagonal;
  const double tol = out.tolerance;
  // A curved fit must also stay near the input's own chordal error over each face (within
  // kChordSlack times chordal_bounds at its centroid and edge midpoints): points on two rims
  // alone lie on many surfaces (a torus bulging between the two rims of a hole's wall, whose
  // vertices are all on the rims, 300 times the wall's chordal error away from its faces),
  // and only the chords tell them apart.
  const std::vector<double> chordal = chordal_bounds(mesh, features, tol);
  auto chords_fit = [&](const Primitive& prim, const std::vector<std::uint32_t>& faces) {
    for (std::uint32_t f : faces) {
      const auto vs = mesh.face_vertices(FaceId(f));
      const Vec3 &a = mesh.position(vs[0]), &b = mesh.position(vs[1]), &c = mesh.position(vs[2]);
      const double allowed = kChordSlack * chordal[f] + tol;
      for (const Vec3& q : {(a + b + c) * (1.0 / 3), (a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5})
        if (!(prim.distance(q) <= allowed)) return false;
    }
    return true;
  };

  // Crease-bounded components: faces joined across edges that are not sharp.
  std::vector<std::int32_t> component(nf, -1);
  std::vector<std::vector<std::uint32_t>> components;
  for (std::uint32_t seed = 0; seed < nf; ++seed) {
    if (component[seed] >= 0) continue;
    const auto id = static_cast<std::int32_t>(components.size());
    components.emplace_back();
    std::vector<std::uint32_t> stack{seed};
    component[seed] = id;
    while (!stack.empty()) {
      const std::uint32_t f = stack.back();
      stack.pop_back();
      components.back().push_back(f);
      for (int k = 0; k < 3; ++k) {
        const HalfedgeId h = Mesh::halfedge(FaceId(f), k);
        if (mesh.is_boundary(h) || features.is_sharp(mesh.edge(h))) continue;
        const std::uint32_t g = Mesh::face(mesh.twin(h)).idx;
        if (component[g] < 0) {
          component[g] = id;
          stack.push_back(g);
        }
      }
    }
  }

  std::vector<std::uint32_t> stamp(mesh.num_vertices(), 0);
  std::uint32_t mark = 0;
  auto add_region = [&](const Primitive& prim, const Patch& patch, double residual, bool grown) {
    const auto id = static_cast<std::int32_t>(out.regions.size());
    Region r;
    r.primitive = prim;
    r.faces = patch.faces.size();
    r.vertices = patch.points.size();
    r.max_residual = residual;
    r.grown = grown;
    out.regions.push_back(r);
    for (std::uint32_t f : patch.faces) out.face_region[f] = id;
  };

  // Components meet across sharp edges; a primitive fitted to one absorbs the neighbours
  // whose vertices all lie on it (a cylinder whose zipped side the crease angle cut apart).
  const std::size_t nc = components.size();
  std::vector<std::vector<std::int32_t>> neighbours(nc);
  for (std::size_t c = 0; c < nc; ++c) {
    for (std::uint32_t f : components[c])
      for (int k = 0; k < 3; ++k) {
        const HalfedgeId h = Mesh::halfedge(FaceId(f), k);
        if (mesh.is_boundary(h)) continue;
        const std::int32_t other = component[Mesh::face(mesh.twin(h)).idx];
        if (other != static_cast<std::int32_t>(c)) neighbours[c].push_back(other);
      }
    std::sort(neighbours[c].begin(), neighbours[c].end());
    neighbours[c].erase(std::unique(neighbours[c].begin(), neighbours[c].end()),
                        neighbours[c].end());
  }
  std::vector<Patch> patches;
  patches.reserve(nc);
  for (std::size_t c = 0; c < nc; ++c)
    patches.push_back(make_patch(mesh, components[c], stamp, ++mark));
  std::vector<std::size_t> order(nc);
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return components[a].size() > components[b].size();
  });
  std::vector<std::uint8_t> assigned(nc, 0);
  // The grown planes' face flags, once for all components (each touches its own faces
  // only): allocated per component they cost a pass over every face for each of a scan's
  // many small components.
  std::vector<std::uint8_t> taken(nf, 0), tried(nf, 0);

  // Planes first; among the curved types the one that absorbs the most faces (two coaxial
  // circles lie on a cylinder or cone and on a sphere: the neighbours decide), ties in this
  // order.
  constexpr PrimitiveType kCurved[] = {PrimitiveType::Cylinder, PrimitiveType::Cone,
                                       PrimitiveType::Sphere, PrimitiveType::Torus};
  // Every planar component first: a cap fanned from its rim has all its vertices on the
  // cylinder too, and must not be absorbed by it.
  for (std::size_t c : order) {
    const Patch& patch = patches[c];
    if (const std::optional<Primitive> plane =
            fit_primitive(PrimitiveType::Plane, patch.points, patch.normals, patch.centroids)) {
      const double residual = max_residual(*plane, patch.points);
      if (residual <= tol) {
        add_region(*plane, patch, residual, false);
        assigned[c] = 1;
      }
    }
  }
  for (std::size_t c : order) {
    if (assigned[c]) continue;
    const Patch& patch = patches[c];
    const std::vector<std::uint32_t>& faces = components[c];
    bool found = false;
    std::optional<Primitive> best;
    std::vector<std::size_t> best_members;
    std::size_t best_faces = 0;
    for (PrimitiveType type : kCurved) {
      const std::optional<Primitive> prim = fit_curved(type, patch, tol);
      if (!prim || max_residual(*prim, patch.points) > tol || !chords_fit(*prim, faces)) continue;
      std::vector<std::size_t> members{c};
      std::vector<std::uint8_t> seen(nc, 0);
      seen[c] = 1;
      std::size_t total = faces.size();
      for (std::size_t i = 0; i < members.size(); ++i)
        for (std::int32_t nb : neighbours[members[i]]) {
          const auto n = static_cast<std::size_t>(nb);
          if (seen[n] || assigned[n]) continue;
          seen[n] = 1;
          if (max_residual(*prim, patches[n].points) > tol || !chords_fit(*prim, components[n]))
            continue;
          members.push_back(n);
          total += components[n].size();
        }
      if (total > best_faces) {
        best = prim;
        best_members = std::move(members);
        best_faces = total;
      }
    }
    if (best) {
      std::vector<std::uint32_t> all;
      for (std::size_t m : best_members) {
        all.insert(all.end(), components[m].begin(), components[m].end());
        assigned[m] = 1;
      }
      const Patch merged = make_patch(mesh, all, stamp, ++mark);
      // Refitted on the union, the first type in kCurved's order that fits every vertex:
      // points on two coaxial circles fit a sphere as well as the cylinder or cone they
      // came from, and the simpler surface is the likelier one (a narrow seed patch may
      // have missed it).
      Primitive use = *best;
      for (PrimitiveType type : kCurved) {
        const std::optional<Primitive> refit = fit_curved(type, merged, tol);
        if (refit && max_residual(*refit, merged.points) <= tol && chords_fit(*refit, all)) {
          use = *refit;
          break;
        }
      }
      // A few points fit any curved surface (6 vertices of two flat faces at an angle lie on
      // a sphere): a curved region needs enough of them to mean something.
      if (merged.points.size() >= min_curved_vertices(use.type)) {
        add_region(use, merged, max_residual(use, merged.points), false);
        found = true;
      } else {
        for (std::size_t mm : best_members)
          if (mm != c) assigned[mm] = 0;
      }
    }
    assigned[c] = 1;
    if (found || faces.size() < 2) continue;

    // Planes grown across smooth edges inside the component, largest faces first.
    std::vector<std::uint32_t> seeds = faces;
    std::vector<double> area(seeds.size());
    for (std::size_t i = 0; i < seeds.size(); ++i)
      area[i] = norm(mesh.face_normal(FaceId(seeds[i])));
    std::vector<std::size_t> order(seeds.size());
    std::iota(order.begin(), order.end(), std::size_t{0});
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return area[a] > area[b]; });
    for (std::size_t oi : order) {
      const std::uint32_t seed = seeds[oi];
      if (taken[seed] || tried[seed] || !(area[oi] > 0)) continue;
      const auto sv = mesh.face_vertices(FaceId(seed));
      Primitive plane;
      plane.type = PrimitiveType::Plane;
      plane.point = mesh.position(sv[0]);
      plane.axis = normalized(mesh.face_normal(FaceId(seed)));
      auto fits = [&](std::uint32_t f) {
        for (VertexId v : mesh.face_vertices(FaceId(f)))
          if (plane.distance(mesh.position(v)) > tol) return false;
        return true;
      };
      std::vector<std::uint32_t> grown{seed}, stack{seed};
      taken[seed] = 2;
      while (!stack.empty()) {
        const std::uint32_t f = stack.back();
        stack.pop_back();
        for (int k = 0; k < 3; ++k) {
          const HalfedgeId h = Mesh::halfedge(FaceId(f), k);
          if (mesh.is_boundary(h) || features.is_sharp(mesh.edge(h))) continue;
          const std::uint32_t g = Mesh::face(mesh.twin(h)).idx;
          if (taken[g] || !fits(g)) continue;
          taken[g] = 2;
          grown.push_back(g);
          stack.push_back(g);
        }
      }
      // A single face is never kept: refused before its patch is made (on a scan nearly
      // every face is such a seed).
      bool keep = false;
      if (grown.size() >= 2) {
        const Patch gp = make_patch(mesh, grown, stamp, ++mark);
        if (gp.area >= 0.05 * patch.area) {
          const std::optional<Primitive> refit =
              fit_primitive(PrimitiveType::Plane, gp.points, gp.normals, gp.centroids);
          const Primitive& use = refit && max_residual(*refit, gp.points) <= tol ? *refit : plane;
          const double residual = max_residual(use, gp.points);
          keep = residual <= tol;
          if (keep) add_region(use, gp, residual, true);
        }
      }
      // Faces of a rejected plane stay free for a larger plane grown from elsewhere, but are
      // not seeds again (they would grow the same plane).
      for (std::uint32_t g : grown) {
        taken[g] = keep ? 1 : 0;
        tried[g] = 1;
      }
    }
  }
  return out;
}

}  // namespace stlrefine::primitives
