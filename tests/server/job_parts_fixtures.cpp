// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "job_parts_fixtures.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <thread>

#include "core/io/mesh_formats.h"
#include "core/mesh/build_mesh.h"
#include "test_stl.h"

namespace stlrefine::test {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

fs::path fresh_job_dir(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / cat("stlrefine-s5-", name, "-", std::to_string(::getpid()));
  fs::remove_all(dir);
  return dir;
}

server::DaemonConfig jobs_config(const fs::path& dir) {
  server::DaemonConfig config;
  config.compute_slots = 2;
  config.http_threads = 8;
  config.max_faces = 4'000'000;
  config.jobs.data_dir = dir;
  config.jobs.max_queued = 8;
  config.shutdown_grace = 5s;
  return config;
}

Box box(float s, float dx) {
  Box b;
  for (int i = 0; i < 8; ++i)
    b.v.push_back({(i & 1) ? s + dx : dx, (i & 2) ? s : 0.0f, (i & 4) ? s : 0.0f});
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                           {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    b.t.push_back({q[0], q[1], q[2]});
    b.t.push_back({q[0], q[2], q[3]});
  }
  return b;
}

std::string stl_of(const Box& b) {
  std::vector<Triangle> tris;
  for (const auto& t : b.t) tris.push_back({b.v[t[0]], b.v[t[1]], b.v[t[2]]});
  return binary_stl(tris);
}

std::string three_mf(const std::vector<std::pair<std::string, Box>>& objects,
                     const std::string& unit) {
  std::vector<Mesh> meshes;
  for (const auto& [name, b] : objects) {
    IndexedSoup soup;
    for (const auto& c : b.v) soup.positions.push_back({c[0], c[1], c[2]});
    for (const auto& t : b.t)
      soup.triangles.push_back({static_cast<std::uint32_t>(t[0]), static_cast<std::uint32_t>(t[1]),
                                static_cast<std::uint32_t>(t[2])});
    meshes.push_back(build_mesh(soup).mesh);
  }
  std::vector<NamedMesh> named;
  for (std::size_t i = 0; i < objects.size(); ++i) named.push_back({objects[i].first, &meshes[i]});
  return write_3mf(named, unit);
}

namespace {
constexpr const char* kBoundary = "----stlrefine-s5-boundary";
}

std::string form_file(const std::string& filename, const std::string& content) {
  std::string body = std::string("--") + kBoundary;
  body.append("\r\nContent-Disposition: form-data; name=\"file\"; filename=\"")
      .append(filename)
      .append("\"\r\nContent-Type: application/octet-stream\r\n\r\n")
      .append(content)
      .append("\r\n--")
      .append(kBoundary)
      .append("--\r\n");
  return body;
}

std::string form_type() {
  return std::string("multipart/form-data; boundary=") + kBoundary;
}

nlohmann::json wait_job(httplib::Client& c, const std::string& location) {
  const auto deadline = std::chrono::steady_clock::now() + 60s;
  nlohmann::json job;
  while (std::chrono::steady_clock::now() < deadline) {
    auto r = c.Get(location.c_str());
    if (r && r->status == 200) {
      job = nlohmann::json::parse(r->body);
      const std::string state = job["state"];
      if (state == "done" || state == "failed" || state == "cancelled") return job;
    }
    std::this_thread::sleep_for(20ms);
  }
  ADD_FAILURE() << "job did not end: " << job.dump();
  return job;
}

}  // namespace stlrefine::test

#include <zlib.h>

namespace stlrefine::test {

namespace {
void le16(std::string& s, unsigned v) {
  s.push_back(static_cast<char>(v & 0xff));
  s.push_back(static_cast<char>((v >> 8) & 0xff));
}
void le32(std::string& s, std::uint32_t v) {
  le16(s, v & 0xffff);
  le16(s, v >> 16);
}
}  // namespace

std::string raw_zip(const std::vector<RawZipEntry>& entries) {
  std::string out, central;
  for (const RawZipEntry& e : entries) {
    const std::uint32_t offset = static_cast<std::uint32_t>(out.size());
    const unsigned flags = e.encrypted ? 1 : 0;
    const unsigned method = e.claimed_size ? 8 : 0;
    const std::uint32_t crc = static_cast<std::uint32_t>(::crc32(
        0, reinterpret_cast<const Bytef*>(e.data.data()), static_cast<uInt>(e.data.size())));
    const std::uint32_t csize = static_cast<std::uint32_t>(e.data.size());
    const std::uint32_t usize = e.claimed_size ? e.claimed_size : csize;
    le32(out, 0x04034b50);
    le16(out, 20);
    le16(out, flags);
    le16(out, method);
    le16(out, 0);
    le16(out, 0x21);
    le32(out, crc);
    le32(out, csize);
    le32(out, usize);
    le16(out, static_cast<unsigned>(e.name.size()));
    le16(out, 0);
    out.append(e.name).append(e.data);
    le32(central, 0x02014b50);
    le16(central, 20);
    le16(central, 20);
    le16(central, flags);
    le16(central, method);
    le16(central, 0);
    le16(central, 0x21);
    le32(central, crc);
    le32(central, csize);
    le32(central, usize);
    le16(central, static_cast<unsigned>(e.name.size()));
    le16(central, 0);
    le16(central, 0);
    le16(central, 0);
    le16(central, 0);
    le32(central, 0);
    le32(central, offset);
    central.append(e.name);
  }
  const std::uint32_t cd_offset = static_cast<std::uint32_t>(out.size());
  out.append(central);
  le32(out, 0x06054b50);
  le16(out, 0);
  le16(out, 0);
  le16(out, static_cast<unsigned>(entries.size()));
  le16(out, static_cast<unsigned>(entries.size()));
  le32(out, static_cast<std::uint32_t>(central.size()));
  le32(out, cd_offset);
  le16(out, 0);
  return out;
}

}  // namespace stlrefine::test
