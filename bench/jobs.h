// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// The measured jobs: our schemes and readers, and the peers a user would pick instead
// (CGAL, and OpenMesh when it was found at configure time).
//
// Every refinement job gets the same input: the oriented manifold mesh our ingest
// (read_stl_file + weld + build_mesh) makes from the file. Peers receive it converted to
// their own structure; conversion is untimed and reported separately.

#include <filesystem>
#include <string>

#include "bench/measure.h"
#include "core/mesh/indexed_soup.h"

namespace stlrefine::bench {

//! Runs our ingest on the file (in a child: it uses TBB). Sample: in_faces = file
//! triangles, out_faces/out_vertices = the ingested mesh, note = boundary and repairs.
Sample describe_input(const std::filesystem::path& path, double crease_angle_deg);

//! The manifold mesh our ingest builds from the file, as positions and triangles (what
//! the peers are given).
IndexedSoup load_ingested_triangles(const std::filesystem::path& path);

// --- ours
JobFactory ours_refine_job(const std::filesystem::path& path, const std::string& scheme, int levels,
                           int threads, double crease_angle_deg);
//! The whole request: STL bytes in memory -> read_stl -> weld -> build_mesh -> refine ->
//! write_stl (binary). Intermediates are freed as soon as the next stage has them.
JobFactory ours_pipeline_job(const std::filesystem::path& path, const std::string& scheme,
                             int levels, int threads, double crease_angle_deg);

enum class OurRead { Buffer, File, FileAndBuild };
JobFactory ours_read_job(const std::filesystem::path& path, OurRead variant);

// --- CGAL
JobFactory cgal_loop_job(const std::filesystem::path& path, int levels);
//! CGAL::Subdivision_method_3::Sqrt3_subdivision (Kobbelt's sqrt3) on a Surface_mesh.
JobFactory cgal_sqrt3_job(const std::filesystem::path& path, int levels);
//! CGAL::IO::read_STL into a polygon soup (points + triangles; CGAL merges equal points).
JobFactory cgal_read_soup_job(const std::filesystem::path& path);
//! CGAL::IO::read_polygon_mesh (BGL): soup, then Surface_mesh only if it is already a
//! valid polygon mesh (fails otherwise).
JobFactory cgal_read_mesh_job(const std::filesystem::path& path);
//! CGAL::Polygon_mesh_processing::IO::read_polygon_mesh: soup, repair, orient, mesh.
JobFactory cgal_read_mesh_repair_job(const std::filesystem::path& path);

// --- OpenMesh (only when built with it)
bool have_openmesh();
JobFactory openmesh_loop_job(const std::filesystem::path& path, int levels);
JobFactory openmesh_butterfly_job(const std::filesystem::path& path, int levels);
//! OpenMesh Sqrt3T (Kobbelt's sqrt3).
JobFactory openmesh_sqrt3_job(const std::filesystem::path& path, int levels);
//! OpenMesh InterpolatingSqrt3LGT (Labsik-Greiner interpolatory sqrt3).
JobFactory openmesh_sqrt3_lg_job(const std::filesystem::path& path, int levels);
//! OpenMesh::IO::read_mesh into a TriMesh (double points).
JobFactory openmesh_read_job(const std::filesystem::path& path);

// --- versions, for the machine section
std::string cgal_version();
std::string openmesh_version();

}  // namespace stlrefine::bench
