// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// stlrefine_memory_calibration: the peak RSS one request adds to an idle stlrefined, next to
// what api/memory_model predicts for it. Each case runs in a fresh daemon (one compute slot,
// a budget far above the case): a warm-up request on an octahedron (thread pool, code pages),
// then the daemon's RSS is the baseline, its peak is reset (/proc/<pid>/clear_refs 5), the
// request runs and is read whole, and the peak minus the baseline is the measurement.
// Jobs are polled until done. Hand-run; the figures and the fit are in memory_model.cpp and
// bench/RESULTS.md ("## Load and soak").
//
//   stlrefine_memory_calibration [--meshes /work/shared/meshes] [--max-out 3500000]
//                                [--csv FILE] [--only SUBSTRING] [--from-csv FILE]
//
// --from-csv takes the measurements of an earlier --csv run and only predicts again (for
// fitting the coefficients without measuring again).

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <span>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "api/memory_model.h"
#include "api/params.h"
#include "core/refine.h"
#include "core/schemes/scheme.h"
#include "daemon_probe.h"
#include "http_test_client.h"  // tests/server
#include "test_stl.h"          // tests/server

namespace {

using namespace stlrefine;
using namespace std::chrono_literals;
namespace fs = std::filesystem;

struct Case {
  std::string mesh;    // path relative to --meshes
  std::string target;  // "/v1/refine?..."
};

struct Input {
  std::string path;
  std::string bytes;
  api::StlShape shape;
};

std::span<const std::uint8_t> as_bytes(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

// The daemon's own limits: the model sees the requests as the daemon parses them.
api::RequestLimits daemon_limits() {
  return {.max_faces = 20'000'000,
          .default_max_faces = 0,
          .max_slice_points = 20'000'000,
          .accept_threads = false};
}

api::MemoryEstimate predict(const Input& mesh, const std::string& target) {
  const std::size_t q = target.find('?');
  const std::string route = target.substr(0, q);
  const api::RawParams raw =
      api::parse_query(q == std::string::npos ? "" : std::string_view(target).substr(q + 1));
  const auto bytes = as_bytes(mesh.bytes);
  if (route == "/v1/refine")
    return api::estimate_refine_memory(bytes, mesh.shape,
                                       api::parse_refine_params(raw, daemon_limits()));
  if (route == "/v1/jobs")
    return api::estimate_refine_memory(bytes, mesh.shape,
                                       api::parse_refine_params(raw, daemon_limits()),
                                       api::ResultSink::JobFiles);
  if (route == "/v1/slice")
    return api::estimate_slice_memory(bytes, mesh.shape,
                                      api::parse_slice_params(raw, daemon_limits()));
  return api::estimate_info_memory(mesh.shape);
}

std::string post(const std::string& target, const std::string& body) {
  return test::post_text(target, "model/stl", body);
}

struct Measured {
  int status = 0;
  long long peak = 0;      // bytes above the baseline
  long long baseline = 0;  // RSS before the request
  std::uint64_t out_faces = 0;
  std::uint64_t points = 0;  // slice points, when sliced
  std::uint64_t answer = 0;  // bytes of the answer
  double seconds = 0;
  std::string error;
};

Measured measure(const std::string& daemon, const Input& mesh, const std::string& target,
                 const fs::path& data_dir) {
  Measured m;
  fs::remove_all(data_dir);
  bench::DaemonProbe d(daemon, {"--compute-slots", "1", "--memory-budget", "20G", "--data-dir",
                                data_dir.string(), "--max-body-mib", "1024"});
  // Warm up the same route on a small part.
  const std::string octa = test::binary_stl(test::octahedron_triangles());
  const std::size_t q = target.find('?');
  const std::string route = target.substr(0, q);
  const std::string warm = route == "/v1/slice"  ? "/v1/slice?layer_height=0.1"
                           : route == "/v1/info" ? "/v1/info"
                                                 : "/v1/refine?levels=1";
  test::exchange(d.port(), post(warm, octa), 30s);
  std::this_thread::sleep_for(200ms);
  m.baseline = d.status_bytes("VmRSS");
  d.reset_peak();
  const auto start = std::chrono::steady_clock::now();
  const std::string raw = test::exchange(d.port(), post(target, mesh.bytes), 600s);
  auto responses = test::parse_responses(raw);
  if (responses.empty()) {
    m.error = "no answer";
    return m;
  }
  test::RawResponse r = responses.front();
  m.status = r.status;
  m.answer = r.body.size();
  nlohmann::json report;
  if (route == "/v1/jobs" && r.status == 202) {
    const std::string location = r.header("location");
    for (;;) {
      std::this_thread::sleep_for(50ms);
      auto got = test::parse_responses(
          test::exchange(d.port(), "GET " + location + " HTTP/1.1\r\nHost: x\r\n\r\n", 30s));
      if (got.empty()) continue;
      const nlohmann::json job = nlohmann::json::parse(got.front().body);
      const std::string state = job.value("state", "");
      if (state == "queued" || state == "running") continue;
      m.status = state == "done" ? 200 : 500;
      if (job.contains("report")) report = job["report"];
      break;
    }
  } else if (r.has_header("x-stlrefine-report")) {
    report = nlohmann::json::parse(r.header("x-stlrefine-report"));
  } else if (route == "/v1/info" && r.status == 200) {
    report = nlohmann::json::parse(r.body);
  }
  m.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  m.peak = d.status_bytes("VmHWM") - m.baseline;
  if (report.contains("output")) m.out_faces = report["output"].value("faces", 0ull);
  if (report.contains("slice")) m.points = report["slice"].value("points", 0ull);
  if (r.status >= 400 && r.status != 202) m.error = r.body.substr(0, 200);
  return m;
}

// Measurements of an earlier run, by mesh + target.
std::map<std::string, Measured> read_csv(const std::string& path) {
  std::map<std::string, Measured> out;
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    // mesh,faces,body_bytes,"target",status,out_faces,points,answer_bytes,measured_bytes,...
    const std::size_t q1 = line.find('"'), q2 = line.find('"', q1 + 1);
    if (q1 == std::string::npos || q2 == std::string::npos) continue;
    const std::string mesh = line.substr(0, line.find(','));
    const std::string target = line.substr(q1 + 1, q2 - q1 - 1);
    std::stringstream rest(line.substr(q2 + 2));
    std::vector<std::string> f;
    for (std::string x; std::getline(rest, x, ',');) f.push_back(x);
    if (f.size() < 9) continue;
    Measured m;
    m.status = std::stoi(f[0]);
    m.out_faces = std::stoull(f[1]);
    m.points = std::stoull(f[2]);
    m.answer = std::stoull(f[3]);
    m.peak = std::stoll(f[4]);
    m.baseline = std::stoll(f[7]);
    m.seconds = std::stod(f[8]);
    out[mesh + " " + target] = m;
  }
  return out;
}

std::vector<Case> cases(const std::vector<Input>& meshes, std::uint64_t max_out) {
  const std::vector<std::string> split4 = {"butterfly", "loop", "lsf", "loop-g2", "butterfly-g1"};
  const std::vector<std::string> sqrt3 = {"sqrt3-interp", "sqrt3", "sqrt3-unified"};
  std::vector<Case> out;
  for (const Input& m : meshes) {
    const bool all_schemes = m.path.find("fandisk") != std::string::npos ||
                             m.path.find("bunny.stl") != std::string::npos;
    const std::uint64_t f = m.shape.faces;
    for (const auto* list : {&split4, &sqrt3}) {
      for (std::size_t i = 0; i < list->size(); ++i) {
        if (!all_schemes && i > 0) continue;
        const std::string& s = (*list)[i];
        const auto scheme = make_scheme(s);
        for (int levels = list == &split4 && i == 0 ? 0 : 1; levels <= 8; ++levels) {
          if (scheme->predict_faces(f, levels) > max_out) break;
          out.push_back({m.path, "/v1/refine?scheme=" + s + "&levels=" + std::to_string(levels)});
        }
      }
    }
    if (f > 200'000) continue;  // the rest on the smaller parts
    out.push_back({m.path, "/v1/info"});
    const double extent = m.shape.z_max - m.shape.z_min;
    char h[32];
    std::snprintf(h, sizeof h, "%.6g", extent / 200);
    for (const char* format : {"json", "svg", "cli", "cli-binary"})
      out.push_back({m.path, std::string("/v1/slice?layer_height=") + h + "&format=" + format});
    std::snprintf(h, sizeof h, "%.6g", extent / 1000);
    out.push_back({m.path, std::string("/v1/slice?layer_height=") + h + "&format=json"});
    if (m.path.find("cycloidal") == std::string::npos) {
      out.push_back({m.path, "/v1/refine?scheme=butterfly&adaptive_angle=10&max_level=4"});
      out.push_back({m.path, "/v1/refine?scheme=lsf&adaptive_angle=5&max_level=3"});
      out.push_back({m.path, "/v1/refine?scheme=sqrt3-interp&adaptive_angle=10&max_level=4"});
    }
    std::snprintf(h, sizeof h, "%.6g", extent / 200);
    if (f * 16 <= max_out) {
      out.push_back({m.path, std::string("/v1/refine?levels=2&slice=") + h + "&slice_format=json"});
      out.push_back(
          {m.path, std::string("/v1/refine?levels=2&slice=") + h + "&slice_format=cli-binary"});
      out.push_back({m.path, "/v1/jobs?levels=2"});
      out.push_back({m.path, std::string("/v1/jobs?levels=2&slice=") + h + "&slice_format=json"});
    }
  }
  return out;
}

double mib(double bytes) {
  return bytes / (1 << 20);
}

}  // namespace

int main(int argc, char** argv) {
  std::string meshes_dir = "/work/shared/meshes";
  std::string daemon = STLREFINED;
  std::string csv_path, only, from_csv;
  std::uint64_t max_out = 3'500'000;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--meshes") meshes_dir = argv[i + 1];
    if (a == "--max-out") max_out = std::stoull(argv[i + 1]);
    if (a == "--csv") csv_path = argv[i + 1];
    if (a == "--only") only = argv[i + 1];
    if (a == "--daemon") daemon = argv[i + 1];
    if (a == "--from-csv") from_csv = argv[i + 1];
  }
  const std::map<std::string, Measured> earlier =
      from_csv.empty() ? std::map<std::string, Measured>() : read_csv(from_csv);
  std::vector<Input> meshes;
  for (const char* name : {"cad/gearwheel.stl", "malformed/gearwheel_ascii.stl", "cad/fandisk.stl",
                           "organic/armadillo.stl", "malformed/cycloidal_nonmanifold.stl",
                           "organic/bunny.stl", "large/dragon_full.stl.gz"}) {
    Input m;
    m.path = name;
    m.bytes = bench::read_input((fs::path(meshes_dir) / name).string());
    if (m.bytes.empty()) {
      std::cerr << "skipping " << name << " (unreadable)\n";
      continue;
    }
    m.shape = api::stl_shape(as_bytes(m.bytes));
    meshes.push_back(std::move(m));
  }
  std::ofstream csv;
  if (!csv_path.empty()) {
    csv.open(csv_path);
    csv << "mesh,faces,body_bytes,target,status,out_faces,points,answer_bytes,measured_bytes,"
           "predicted_bytes,predicted_out_faces,predicted_points,baseline_bytes,seconds\n";
  }
  const fs::path data_dir = fs::temp_directory_path() / "stlrefine-memory-calibration";
  std::cout << "| mesh | faces in | request | faces out | measured MiB | predicted MiB | "
               "predicted / measured |\n|---|---:|---|---:|---:|---:|---:|\n";
  double worst_under = 1e9, worst_over = 0;
  for (const Case& c : cases(meshes, max_out)) {
    if (!only.empty() && (c.mesh + c.target).find(only) == std::string::npos) continue;
    const Input& mesh = *std::find_if(meshes.begin(), meshes.end(),
                                      [&](const Input& m) { return m.path == c.mesh; });
    api::MemoryEstimate e;
    try {
      e = predict(mesh, c.target);
    } catch (const std::exception& ex) {
      std::cerr << c.mesh << " " << c.target << ": no prediction: " << ex.what() << "\n";
      continue;
    }
    Measured m;
    if (from_csv.empty()) {
      m = measure(daemon, mesh, c.target, data_dir);
    } else {
      const auto it = earlier.find(c.mesh + " " + c.target);
      if (it == earlier.end()) continue;
      m = it->second;
    }
    if (m.status != 200) {
      std::cerr << c.mesh << " " << c.target << ": status " << m.status << " " << m.error << "\n";
      continue;
    }
    const double ratio = double(e.peak_bytes) / double(std::max(1ll, m.peak));
    const bool adaptive = c.target.find("adaptive") != std::string::npos;
    if (!adaptive) {
      worst_under = std::min(worst_under, ratio);
      worst_over = std::max(worst_over, ratio);
    }
    char row[512];
    std::snprintf(row, sizeof row, "| %s | %llu | `%s` | %llu | %.1f | %.1f | %.2f |\n",
                  c.mesh.c_str(), static_cast<unsigned long long>(mesh.shape.faces),
                  c.target.c_str(), static_cast<unsigned long long>(m.out_faces), mib(m.peak),
                  mib(double(e.peak_bytes)), ratio);
    std::cout << row << std::flush;
    if (csv.is_open())
      csv << c.mesh << "," << mesh.shape.faces << "," << mesh.bytes.size() << ",\"" << c.target
          << "\"," << m.status << "," << m.out_faces << "," << m.points << "," << m.answer << ","
          << m.peak << "," << e.peak_bytes << "," << e.output_faces << "," << e.contour_points
          << "," << m.baseline << "," << m.seconds << std::endl;
  }
  fs::remove_all(data_dir);
  std::cout << "\npredicted / measured over the uniform, slice, info and job rows: " << worst_under
            << " .. " << worst_over << "\n";
  return 0;
}
