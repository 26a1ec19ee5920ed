// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include <cstdint>
#include <fstream>
#include <iterator>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "bench/jobs.h"
#include "core/features/features.h"
#include "core/io/stl.h"
#include "core/mesh/build_mesh.h"
#include "core/refine.h"

namespace stlrefine::bench {
namespace {

namespace fs = std::filesystem;

std::vector<std::uint8_t> read_file_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot open " + path.string());
  std::vector<std::uint8_t> bytes(fs::file_size(path));
  in.read(reinterpret_cast<char*>(bytes.data()), std::streamsize(bytes.size()));
  if (!in) throw std::runtime_error("cannot read " + path.string());
  return bytes;
}

std::uint64_t stl_header_triangles(const fs::path& path) {
  const auto size = fs::file_size(path);
  return size >= 84 ? (size - 84) / 50 : 0;
}

std::size_t boundary_halfedges(const Mesh& mesh) {
  std::size_t n = 0;
  for (const HalfedgeId t : mesh.twins()) n += t.valid() ? 0 : 1;
  return n;
}

RefineParams make_params(const std::string& scheme, int levels, int threads,
                         double crease_angle_deg) {
  RefineParams params;
  params.scheme = scheme;
  params.levels = levels;
  params.threads = threads;
  params.max_faces = (std::uint64_t(1) << 31) - 1;  // the bench decides what is too big
  params.features.crease_angle_deg = crease_angle_deg;
  return params;
}

//! What the table shows for our runs: feature counts are in the input line, so only the
//! fold guard's interventions (a sign of trouble worth seeing next to the time).
std::string describe_report(const RefineReport& r) {
  return r.fold_fallbacks > 0 ? "fold fallbacks " + std::to_string(r.fold_fallbacks) : "";
}

class OursRefine final : public Job {
 public:
  OursRefine(const fs::path& path, RefineParams params) : params_(std::move(params)) {
    IngestResult ingest = build_mesh(weld(read_stl_file(path)));
    input_ = std::move(ingest.mesh);
    in_faces_ = input_.num_faces();
  }
  // The input is moved in, as the service does (api/pipeline.cpp) and as the peers refine
  // their converted mesh in place: copying it is not part of refining (each run is a new job).
  void run() override { result_ = refine(std::move(input_), params_); }
  std::uint64_t in_faces() const override { return in_faces_; }
  std::uint64_t out_faces() const override { return result_.mesh.num_faces(); }
  std::uint64_t out_vertices() const override { return result_.mesh.num_vertices(); }
  std::string note() const override { return describe_report(result_.report); }

 private:
  RefineParams params_;
  Mesh input_;
  std::uint64_t in_faces_ = 0;
  RefineResult result_;
};

class OursPipeline final : public Job {
 public:
  OursPipeline(const fs::path& path, RefineParams params)
      : params_(std::move(params)), bytes_(read_file_bytes(path)) {}
  void run() override {
    IndexedSoup welded;
    {
      const TriangleSoup soup = read_stl(bytes_);
      welded = weld(soup);
    }
    IngestResult ingest = build_mesh(welded);
    welded = IndexedSoup{};
    in_faces_ = ingest.mesh.num_faces();
    RefineResult result = refine(std::move(ingest.mesh), params_);
    ingest = IngestResult{};
    out_faces_ = result.mesh.num_faces();
    out_vertices_ = result.mesh.num_vertices();
    report_ = result.report;
    stl_ = write_stl(result.mesh);
  }
  std::uint64_t in_faces() const override { return in_faces_; }
  std::uint64_t out_faces() const override { return out_faces_; }
  std::uint64_t out_vertices() const override { return out_vertices_; }
  std::string note() const override {
    const std::string folds = describe_report(report_);
    return "output STL " + std::to_string(stl_.size()) + " bytes" +
           (folds.empty() ? "" : "; " + folds);
  }

 private:
  RefineParams params_;
  std::vector<std::uint8_t> bytes_;
  std::uint64_t in_faces_ = 0, out_faces_ = 0, out_vertices_ = 0;
  RefineReport report_;
  std::string stl_;
};

class OursRead final : public Job {
 public:
  OursRead(const fs::path& path, OurRead variant) : path_(path), variant_(variant) {
    if (variant_ == OurRead::Buffer) bytes_ = read_file_bytes(path);
  }
  void run() override {
    switch (variant_) {
      case OurRead::Buffer: {
        welded_ = weld(read_stl(bytes_));
        faces_ = welded_.triangles.size();
        vertices_ = welded_.positions.size();
        break;
      }
      case OurRead::File: {
        welded_ = weld(read_stl_file(path_));
        faces_ = welded_.triangles.size();
        vertices_ = welded_.positions.size();
        break;
      }
      case OurRead::FileAndBuild: {
        ingest_ = build_mesh(weld(read_stl_file(path_)));
        faces_ = ingest_.mesh.num_faces();
        vertices_ = ingest_.mesh.num_vertices();
        break;
      }
    }
  }
  std::uint64_t in_faces() const override { return stl_header_triangles(path_); }
  std::uint64_t out_faces() const override { return faces_; }
  std::uint64_t out_vertices() const override { return vertices_; }

 private:
  fs::path path_;
  OurRead variant_;
  std::vector<std::uint8_t> bytes_;
  IndexedSoup welded_;
  IngestResult ingest_;
  std::uint64_t faces_ = 0, vertices_ = 0;
};

}  // namespace

Sample describe_input(const fs::path& path, double crease_angle_deg) {
  Sample sample;
  const IngestResult ingest = build_mesh(weld(read_stl_file(path)));
  const IngestReport& r = ingest.report;
  sample.in_faces = r.input_triangles;
  sample.out_faces = ingest.mesh.num_faces();
  sample.out_vertices = ingest.mesh.num_vertices();
  std::ostringstream note;
  note << boundary_halfedges(ingest.mesh) << " boundary edges";
  const auto add = [&](std::size_t n, const char* what) {
    if (n > 0) note << ", " << n << ' ' << what;
  };
  add(r.index_degenerate_removed, "index-degenerate facets removed");
  add(r.zero_area_faces, "zero-area facets kept");
  add(r.isolated_vertices_removed, "isolated vertices removed");
  add(r.non_manifold_edges, "non-manifold edges cut");
  add(r.non_manifold_vertices, "non-manifold vertices split");
  add(r.faces_reoriented, "facets reoriented");
  add(r.non_orientable_cuts, "non-orientable cuts");
  FeatureParams params;
  params.crease_angle_deg = crease_angle_deg;
  const Features features = detect_features(ingest.mesh, params);
  note << "; " << features.num_sharp_edges() << " sharp edges at " << crease_angle_deg
       << " deg (incl. boundary): " << features.count(VertexKind::Corner) << " corners, "
       << features.count(VertexKind::Crease) << " crease and " << features.count(VertexKind::Dart)
       << " dart vertices";
  copy_note(sample, note.str());
  return sample;
}

IndexedSoup load_ingested_triangles(const fs::path& path) {
  const IngestResult ingest = build_mesh(weld(read_stl_file(path)));
  const Mesh& mesh = ingest.mesh;
  IndexedSoup soup;
  soup.positions.assign(mesh.positions().begin(), mesh.positions().end());
  soup.triangles.resize(mesh.num_faces());
  for (std::size_t f = 0; f < mesh.num_faces(); ++f) {
    const auto v = mesh.face_vertices(FaceId(std::uint32_t(f)));
    soup.triangles[f] = {v[0].idx, v[1].idx, v[2].idx};
  }
  return soup;
}

JobFactory ours_refine_job(const fs::path& path, const std::string& scheme, int levels, int threads,
                           double crease_angle_deg) {
  const RefineParams params = make_params(scheme, levels, threads, crease_angle_deg);
  return [path, params] { return std::make_unique<OursRefine>(path, params); };
}

JobFactory ours_pipeline_job(const fs::path& path, const std::string& scheme, int levels,
                             int threads, double crease_angle_deg) {
  const RefineParams params = make_params(scheme, levels, threads, crease_angle_deg);
  return [path, params] { return std::make_unique<OursPipeline>(path, params); };
}

JobFactory ours_read_job(const fs::path& path, OurRead variant) {
  return [path, variant] { return std::make_unique<OursRead>(path, variant); };
}

}  // namespace stlrefine::bench
