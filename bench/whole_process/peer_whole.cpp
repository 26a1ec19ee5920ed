// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
// A peer's whole process on one STL, each phase with the library's own tools, for the
// side-by-side run of bench/whole_process/run.sh (issue 18 item 5):
//   peer_whole cgal-loop IN.stl LEVELS OUT.stl          CGAL 5 read_polygon_mesh ->
//                                                       Loop_subdivision -> write_STL (binary)
//   peer_whole ours-loop|ours-butterfly[-off] IN.stl LEVELS OUT.stl   what `stlrefine refine`
//                                                       does (read the file, run_refine_to_mesh,
//                                                       the streamed atomic write), per phase;
//                                                       "-off": max_deviation=off; "-string":
//                                                       the STL made whole in memory first, then
//                                                       written (the way before issue 18)
//   peer_whole openmesh-butterfly IN.stl LEVELS OUT.stl OpenMesh read_mesh ->
//                                                       ModifiedButterflyT -> write_mesh (binary)
// Prints one line: peer, faces in/out, seconds read/refine/write/total, peak RSS (MiB,
// getrusage of this process). Hand-run; never a ctest test.
#include <CGAL/Simple_cartesian.h>
#include <CGAL/Subdivision_method_3/subdivision_methods_3.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/boost/graph/IO/polygon_mesh_io.h>
#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <vector>

#include "api/params.h"
#include "api/pipeline.h"
#include "core/io/stl.h"

#ifdef STLREFINE_PEER_WHOLE_OPENMESH
#include <OpenMesh/Core/IO/MeshIO.hh>
// MeshIO.hh must come before the mesh kernel so the readers are registered.
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Tools/Subdivider/Uniform/ModifiedButterFlyT.hh>
#endif

namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}
double peak_mib() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_maxrss) / 1024.0;
}

struct Phases {
  double read = 0, refine = 0, write = 0;
  std::size_t in_faces = 0, out_faces = 0;
  std::string more;    // ours: the report's phases
  double untimed = 0;  // ours: making the bytes alone, not part of the whole process
};

//! The CLI's steps with its defaults (threads: all), timed.
Phases ours(const std::string& scheme, bool deviation, bool string, const std::string& in,
            int levels, const std::string& out) {
  using namespace stlrefine;
  Phases p;
  auto t = Clock::now();
  std::ifstream file(in, std::ios::binary);
  const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(file)),
                                        std::istreambuf_iterator<char>());
  p.read = since(t);
  api::RawParams raw;
  raw.emplace_back("scheme", scheme);
  raw.emplace_back("levels", std::to_string(levels));
  if (!deviation) raw.emplace_back("max_deviation", "off");
  api::RequestLimits limits;
  limits.max_faces = (std::uint64_t{1} << 31) - 1;
  limits.accept_threads = true;
  const api::RefineRequest request = api::parse_refine_params(raw, limits);
  t = Clock::now();
  api::RefinedMesh refined = api::run_refine_to_mesh(bytes, request);
  p.refine = since(t);  // ingest, refine and the deviation pass: see `more`
  const auto& r = refined.outcome.report;
  p.in_faces = r["input"]["faces"].get<std::size_t>();
  p.out_faces = refined.mesh.num_faces();
  char text[256];
  std::snprintf(text, sizeof text, " (ingest %.3f refine %.3f deviation %.3f detect %.3f)",
                r["seconds"]["ingest"].get<double>(), r["seconds"]["refine"].get<double>(),
                r.contains("deviation") ? r["deviation"]["seconds"].get<double>() : 0.0,
                r.contains("deviation") ? r["deviation"]["detect_seconds"].get<double>() : 0.0);
  p.more = text;
  if (string) {
    t = Clock::now();
    const std::string whole = write_stl(refined.mesh);
    write_file_atomically(out, whole);
    p.write = since(t);
    return p;
  }
  // Making the bytes alone (no file), then the streamed atomic write (with its fsyncs).
  t = Clock::now();
  std::uint64_t made = 0;
  write_binary_stl(refined.mesh, [&](std::string_view piece) { made += piece.size(); });
  const double encode = since(t);
  p.untimed = encode;
  t = Clock::now();
  write_stl_file(out, refined.mesh);
  p.write = since(t);
  std::snprintf(text, sizeof text, " (making the %llu bytes alone %.3f, not in total)",
                static_cast<unsigned long long>(made), encode);
  p.more += text;
  return p;
}

Phases cgal_loop(const std::string& in, int levels, const std::string& out) {
  using Mesh = CGAL::Surface_mesh<CGAL::Simple_cartesian<double>::Point_3>;
  Phases p;
  Mesh mesh;
  auto t = Clock::now();
  if (!CGAL::IO::read_polygon_mesh(in, mesh)) throw std::runtime_error("CGAL cannot read " + in);
  p.read = since(t);
  p.in_faces = mesh.number_of_faces();
  t = Clock::now();
  CGAL::Subdivision_method_3::Loop_subdivision(mesh,
                                               CGAL::parameters::number_of_iterations(levels));
  p.refine = since(t);
  p.out_faces = mesh.number_of_faces();
  t = Clock::now();
  if (!CGAL::IO::write_STL(out, mesh, CGAL::parameters::use_binary_mode(true)))
    throw std::runtime_error("CGAL cannot write " + out);
  p.write = since(t);
  return p;
}

#ifdef STLREFINE_PEER_WHOLE_OPENMESH
Phases openmesh_butterfly(const std::string& in, int levels, const std::string& out) {
  struct Traits : OpenMesh::DefaultTraits {
    using Point = OpenMesh::Vec3d;
    using Normal = OpenMesh::Vec3d;
  };
  using Mesh = OpenMesh::TriMesh_ArrayKernelT<Traits>;
  Phases p;
  Mesh mesh;
  auto t = Clock::now();
  if (!OpenMesh::IO::read_mesh(mesh, in)) throw std::runtime_error("OpenMesh cannot read " + in);
  p.read = since(t);
  p.in_faces = mesh.n_faces();
  t = Clock::now();
  OpenMesh::Subdivider::Uniform::ModifiedButterflyT<Mesh, double> subdivider;
  subdivider.attach(mesh);
  if (!subdivider(std::size_t(levels))) throw std::runtime_error("ModifiedButterflyT failed");
  subdivider.detach();
  p.refine = since(t);
  p.out_faces = mesh.n_faces();
  t = Clock::now();
  if (!OpenMesh::IO::write_mesh(mesh, out, OpenMesh::IO::Options::Binary))
    throw std::runtime_error("OpenMesh cannot write " + out);
  p.write = since(t);
  return p;
}
#endif

}  // namespace

int main(int argc, char** argv) {
  if (argc != 5) {
    std::fprintf(
        stderr,
        "usage: peer_whole ours-SCHEME[-off]|cgal-loop|openmesh-butterfly IN.stl LEVELS OUT.stl\n");
    return 2;
  }
  const std::string peer = argv[1];
  const int levels = std::atoi(argv[3]);
  try {
    const auto start = Clock::now();
    Phases p;
    if (peer.rfind("ours-", 0) == 0) {
      const bool off = peer.find("-off") != std::string::npos;
      const bool string = peer.find("-string") != std::string::npos;
      const std::string scheme = peer.substr(5, peer.find('-', 5) - 5);
      p = ours(scheme, !off, string, argv[2], levels, argv[4]);
    } else if (peer == "cgal-loop") {
      p = cgal_loop(argv[2], levels, argv[4]);
#ifdef STLREFINE_PEER_WHOLE_OPENMESH
    } else if (peer == "openmesh-butterfly") {
      p = openmesh_butterfly(argv[2], levels, argv[4]);
#endif
    } else {
      std::fprintf(stderr, "unknown or unavailable peer %s\n", peer.c_str());
      return 2;
    }
    const double total = since(start) - p.untimed;
    std::printf(
        "%s faces %zu -> %zu read %.3f refine %.3f%s write %.3f total %.3f peak_rss_mib %.1f\n",
        peer.c_str(), p.in_faces, p.out_faces, p.read, p.refine, p.more.c_str(), p.write, total,
        peak_mib());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
  return 0;
}
