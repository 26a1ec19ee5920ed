// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
// Stubs used when CMake did not find OpenMesh: the OpenMesh rows are left out.
#include <stdexcept>

#include "bench/jobs.h"

namespace stlrefine::bench {
namespace {

JobFactory missing() {
  return []() -> std::unique_ptr<Job> { throw std::runtime_error("built without OpenMesh"); };
}

}  // namespace

bool have_openmesh() {
  return false;
}
JobFactory openmesh_loop_job(const std::filesystem::path&, int) {
  return missing();
}
JobFactory openmesh_butterfly_job(const std::filesystem::path&, int) {
  return missing();
}
JobFactory openmesh_sqrt3_job(const std::filesystem::path&, int) {
  return missing();
}
JobFactory openmesh_sqrt3_lg_job(const std::filesystem::path&, int) {
  return missing();
}
JobFactory openmesh_read_job(const std::filesystem::path&) {
  return missing();
}
std::string openmesh_version() {
  return "not built";
}

}  // namespace stlrefine::bench
