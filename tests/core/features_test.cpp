// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/features/features.h"

#include <gtest/gtest.h>

#include <cmath>
#include <initializer_list>
#include <limits>
#include <numbers>
#include <set>
#include <string>
#include <vector>

#include "core/error.h"
#include "tests/core/test_util.h"
#include "tests/support/mesh_queries.h"
#include "tests/support/shapes.h"

namespace stlrefine::test {
namespace {

Features features_of(const Mesh& m, double angle) {
  FeatureParams p;
  p.crease_angle_deg = angle;
  p.crease_mode = CreaseMode::Angle;
  return detect_features(m, p);
}

TEST(Features, DefaultCreaseAngleIs35) {
  EXPECT_EQ(FeatureParams{}.crease_angle_deg, 35.0);
}

TEST(Features, CubeHasTwelveSharpEdgesAndEightCorners) {
  const Mesh m = to_mesh(cube_soup(1.0));
  const Features f = features_of(m, 35.0);
  EXPECT_EQ(f.num_sharp_edges(), 12u);
  EXPECT_EQ(f.count(VertexKind::Corner), 8u);
  EXPECT_EQ(f.count(VertexKind::Crease), 0u);
  EXPECT_EQ(f.count(VertexKind::Smooth), 0u);
  std::size_t flagged = 0;
  for (std::uint32_t e = 0; e < m.num_edges(); ++e) {
    const HalfedgeId h = m.halfedge(EdgeId(e));
    const Vec3 d = m.position(m.to(h)) - m.position(m.from(h));
    // Cube edges are axis-parallel; face diagonals are not.
    const bool cube_edge = (d.x != 0) + (d.y != 0) + (d.z != 0) == 1;
    EXPECT_EQ(f.is_sharp(EdgeId(e)), cube_edge) << "edge " << e;
    EXPECT_NEAR(dihedral_angle_deg(m, EdgeId(e)), cube_edge ? 90.0 : 0.0, 1e-9);
    flagged += f.sharp_edges()[e] != 0;
  }
  EXPECT_EQ(flagged, 12u);
  for (std::uint32_t v = 0; v < 8; ++v) {
    EXPECT_EQ(f.kind(VertexId(v)), VertexKind::Corner);
    EXPECT_TRUE(f.cuts_ring(VertexId(v)));
  }
}

TEST(Features, CreaseAngle180DisablesCreases) {
  const Mesh m = to_mesh(cube_soup(1.0));
  const Features f = features_of(m, 180.0);
  EXPECT_EQ(f.num_sharp_edges(), 0u);
  EXPECT_EQ(f.count(VertexKind::Smooth), 8u);
  // A tetrahedron's normals differ by 109.47 degrees: still smooth at 180.
  const Features t = features_of(to_mesh(tetrahedron_soup()), 180.0);
  EXPECT_EQ(t.num_sharp_edges(), 0u);
}

TEST(Features, ThresholdIsStrict) {
  // Octahedron normals differ by 180 - 109.4712 = 70.5288 degrees.
  const Mesh m = to_mesh(octahedron_soup());
  const double angle = 180.0 - std::acos(-1.0 / 3.0) * 180.0 / std::numbers::pi;
  for (std::uint32_t e = 0; e < m.num_edges(); ++e)
    EXPECT_NEAR(dihedral_angle_deg(m, EdgeId(e)), angle, 1e-9);
  EXPECT_EQ(features_of(m, 70.0).num_sharp_edges(), 12u);
  EXPECT_EQ(features_of(m, 71.0).num_sharp_edges(), 0u);
  EXPECT_EQ(features_of(m, angle - 0.01).num_sharp_edges(), 12u);
  EXPECT_EQ(features_of(m, angle + 0.01).num_sharp_edges(), 0u);
  EXPECT_EQ(features_of(m, 70.0).count(VertexKind::Corner), 6u);
}

TEST(Features, OpenGridBoundaryIsCrease) {
  const int nx = 4, ny = 3;
  const IndexedSoup soup = grid_soup(nx, ny);
  const Mesh m = to_mesh(soup);
  // Even with crease detection off, boundary edges are sharp.
  for (double angle : {35.0, 180.0}) {
    const Features f = features_of(m, angle);
    EXPECT_EQ(f.num_sharp_edges(), static_cast<std::size_t>(2 * (nx + ny)));
    for (std::uint32_t e = 0; e < m.num_edges(); ++e)
      EXPECT_EQ(f.is_sharp(EdgeId(e)), m.is_boundary(EdgeId(e)));
    for (std::uint32_t v = 0; v < m.num_vertices(); ++v) {
      // The 4 grid corners have exactly 2 boundary edges too: Crease, not Corner.
      EXPECT_EQ(f.kind(VertexId(v)),
                m.is_boundary(VertexId(v)) ? VertexKind::Crease : VertexKind::Smooth);
    }
    EXPECT_EQ(f.count(VertexKind::Crease), static_cast<std::size_t>(2 * (nx + ny)));
    EXPECT_EQ(f.count(VertexKind::Corner), 0u);
    const VertexId corner = find_vertex(m, soup.positions[grid_index(nx, 0, 0)]);
    const auto cn = f.curve_neighbours(corner);
    const Vec3 a = m.position(cn[0]), b = m.position(cn[1]);
    const bool ok =
        (a == Vec3{1, 0, 0} && b == Vec3{0, 1, 0}) || (a == Vec3{0, 1, 0} && b == Vec3{1, 0, 0});
    EXPECT_TRUE(ok) << str(a) << " " << str(b);
  }
}

TEST(Features, CylinderRimsAreSharpSidesAreNot) {
  const int n = 24;
  const Mesh m = to_mesh(cylinder_soup(n, 10, 20));
  const Features f = features_of(m, 35.0);
  EXPECT_EQ(f.num_sharp_edges(), static_cast<std::size_t>(2 * n));
  std::size_t side_vertical = 0;
  for (std::uint32_t e = 0; e < m.num_edges(); ++e) {
    const HalfedgeId h = m.halfedge(EdgeId(e));
    const Vec3 a = m.position(m.from(h)), b = m.position(m.to(h));
    const bool rim = a.z == b.z && std::hypot(a.x, a.y) > 9 && std::hypot(b.x, b.y) > 9;
    EXPECT_EQ(f.is_sharp(EdgeId(e)), rim) << str(a) << " " << str(b);
    if (rim) {
      EXPECT_NEAR(dihedral_angle_deg(m, EdgeId(e)), 90.0, 1e-9);
    }
    if (a.x == b.x && a.y == b.y) {  // vertical side edge between two side quads
      ++side_vertical;
      EXPECT_NEAR(dihedral_angle_deg(m, EdgeId(e)), 360.0 / n, 1e-9);
    }
  }
  EXPECT_EQ(side_vertical, static_cast<std::size_t>(n));
  EXPECT_EQ(f.count(VertexKind::Crease), static_cast<std::size_t>(2 * n));
  EXPECT_EQ(f.count(VertexKind::Smooth), 2u);  // the cap centres
}

TEST(Features, CoarseCylinderSideEdgesBecomeCreases) {
  // 8 segments: 45 degrees between side facets, above the default 35.
  const Mesh m = to_mesh(cylinder_soup(8, 10, 100));
  EXPECT_EQ(features_of(m, 35.0).num_sharp_edges(), 8u + 16u);
  EXPECT_EQ(features_of(m, 35.0).count(VertexKind::Corner), 16u);
  EXPECT_EQ(features_of(m, 50.0).num_sharp_edges(), 16u);
}

TEST(Features, KindsFromTaggedEdges) {
  // Polyline (1,2)-(2,2)-(3,2)-(3,3) and a spur (2,2)-(2,1) on a 5x5 grid.
  const int nx = 5;
  const IndexedSoup soup = grid_soup(nx, 5);
  const Mesh m = to_mesh(soup);
  auto V = [&](int i, int j) { return find_vertex(m, soup.positions[grid_index(nx, i, j)]); };
  const Level level = make_level_with_sharp(
      m, {{V(1, 2), V(2, 2)}, {V(2, 2), V(3, 2)}, {V(3, 2), V(3, 3)}, {V(2, 2), V(2, 1)}});
  const Features& f = level.features;
  EXPECT_EQ(f.num_sharp_edges(), 4u + 20u);  // tagged + boundary
  EXPECT_EQ(f.kind(V(1, 2)), VertexKind::Dart);
  EXPECT_EQ(f.kind(V(2, 1)), VertexKind::Dart);
  EXPECT_EQ(f.kind(V(3, 3)), VertexKind::Dart);
  EXPECT_EQ(f.kind(V(2, 2)), VertexKind::Corner);
  EXPECT_EQ(f.kind(V(3, 2)), VertexKind::Crease);
  EXPECT_EQ(f.kind(V(1, 1)), VertexKind::Smooth);
  EXPECT_EQ(f.count(VertexKind::Dart), 3u);
  EXPECT_EQ(f.count(VertexKind::Corner), 1u);
  EXPECT_EQ(f.count(VertexKind::Crease), 1u + 20u);
  EXPECT_FALSE(f.cuts_ring(V(1, 2)));
  EXPECT_TRUE(f.cuts_ring(V(3, 2)));
  const auto cn = f.curve_neighbours(V(3, 2));
  EXPECT_TRUE((cn[0] == V(2, 2) && cn[1] == V(3, 3)) || (cn[0] == V(3, 3) && cn[1] == V(2, 2)));
}

TEST(Features, BoundaryIsForcedSharpInConstructor) {
  const Mesh m = to_mesh(grid_soup(3, 3));
  const Features f(m, BigVector<std::uint8_t>(m.num_edges(), 0));
  EXPECT_EQ(f.num_sharp_edges(), 12u);
  for (std::uint32_t e = 0; e < m.num_edges(); ++e)
    EXPECT_EQ(f.is_sharp(EdgeId(e)), m.is_boundary(EdgeId(e)));
}

TEST(Features, BoundaryDihedralIsZero) {
  const Mesh m = to_mesh(grid_soup(2, 2));
  for (std::uint32_t e = 0; e < m.num_edges(); ++e)
    EXPECT_EQ(dihedral_angle_deg(m, EdgeId(e)), 0.0);
}

// The field is named after the parameter ("crease_angle" in the API, crease_angle_deg in
// FeatureParams): either spelling names it.
TEST(Features, ValidateRejectsOutOfRangeAngles) {
  for (double bad : {-1.0, 181.0, -1e-9, std::numeric_limits<double>::quiet_NaN(),
                     std::numeric_limits<double>::infinity()}) {
    FeatureParams p;
    p.crease_angle_deg = bad;
    try {
      p.validate();
      ADD_FAILURE() << "accepted " << bad;
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::InvalidParameter);
      EXPECT_NE(e.field().find("crease_angle"), std::string::npos) << e.field();
    }
  }
  for (double good : {0.0, 35.0, 180.0}) {
    FeatureParams p;
    p.crease_angle_deg = good;
    EXPECT_NO_THROW(p.validate());
  }
}

TEST(Features, KindNamesAreDistinct) {
  std::set<std::string> names;
  for (VertexKind k :
       {VertexKind::Smooth, VertexKind::Dart, VertexKind::Crease, VertexKind::Corner}) {
    ASSERT_NE(to_string(k), nullptr);
    EXPECT_FALSE(std::string(to_string(k)).empty());
    names.insert(to_string(k));
  }
  EXPECT_EQ(names.size(), 4u);
}

// The section fit behind auto mode's smoothness test (issue 17 item 5): a fillet's section
// is a circle through the edge; its tangent there tells a tangent-continuous fillet (0) from
// one meeting the plane at a crease, however coarse the points.
std::vector<SectionPoint> on_circle(double radius, double crease_deg,
                                    std::initializer_list<double> arc_deg) {
  // The circle leaves the origin at elevation `crease` (tangent (cos c, sin c)) and bends
  // towards +h (its normal (-sin c, cos c)); a point t degrees along it is at
  // R sin(t) tangent + R (1 - cos(t)) normal.
  const double c = crease_deg * std::numbers::pi / 180.0;
  std::vector<SectionPoint> pts;
  for (const double t : arc_deg) {
    const double a = t * std::numbers::pi / 180.0;
    const double s = radius * std::sin(a), k = radius * (1 - std::cos(a));
    pts.push_back({s * std::cos(c) - k * std::sin(c), s * std::sin(c) + k * std::cos(c)});
  }
  return pts;
}

TEST(SectionTangent, TangentFilletIsSmoothAtAnyCoarseness) {
  for (const auto& arcs :
       {std::initializer_list<double>{20, 45}, std::initializer_list<double>{35, 38, 80},
        std::initializer_list<double>{5, 9, 14}}) {
    const std::vector<SectionPoint> pts = on_circle(4.0, 0.0, arcs);
    const auto t = section_tangent(pts);
    ASSERT_TRUE(t.has_value());
    EXPECT_TRUE(t->fitted);
    EXPECT_NEAR(t->elevation, 0.0, 1e-9);
    EXPECT_NEAR(t->radius, 4.0, 1e-9);
  }
}

TEST(SectionTangent, FilletMeetingThePlaneAtACreaseGivesItsAngle) {
  for (const double crease : {6.0, 12.0, -8.0}) {
    const auto t = section_tangent(on_circle(10.0, crease, {15, 40}));
    ASSERT_TRUE(t.has_value());
    EXPECT_NEAR(t->elevation * 180.0 / std::numbers::pi, crease, 1e-9);
  }
}

TEST(SectionTangent, PointsThatFixNoCircleGiveTheirChord) {
  EXPECT_FALSE(section_tangent({}).has_value());
  // One point, or points in one direction (a planar facet): the chord, no radius.
  const std::vector<SectionPoint> line{{1.0, 0.2}, {2.0, 0.4}, {3.0, 0.6}};
  const auto t = section_tangent(line);
  ASSERT_TRUE(t.has_value());
  EXPECT_FALSE(t->fitted);
  EXPECT_NEAR(t->elevation, std::atan(0.2), 1e-12);
  EXPECT_EQ(t->radius, HUGE_VAL);
  // Two points at nearly one distance from the edge: no circle either (a coarse fillet's
  // two ends sampled alike), their mean direction.
  const std::vector<SectionPoint> alike{{1.0, 0.10}, {1.0, 0.14}};
  const auto u = section_tangent(alike);
  ASSERT_TRUE(u.has_value());
  EXPECT_FALSE(u->fitted);
  EXPECT_NEAR(u->elevation, 0.5 * (std::atan(0.10) + std::atan(0.14)), 1e-12);
}

}  // namespace
}  // namespace stlrefine::test
