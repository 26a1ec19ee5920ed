// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <cstdint>
#include <memory>
#include <string_view>
#include <utility>

#include "core/schemes/scheme.h"

namespace stlrefine {

//! The topology host of a stencil family, specialised next to each host (split4_host.h for
//! Split4Stencil, sqrt3_host.h for Sqrt3Stencil): how many faces one step makes of one
//! face, and the step itself.
template <class Stencil>
struct Host;

//! A Scheme made of a topology host and one stencil of its family: HostScheme<Split4Stencil>
//! (loop, butterfly, lsf, loop-g2, butterfly-g1), HostScheme<Sqrt3Stencil> (the sqrt3 family).
template <class Stencil>
class HostScheme final : public Scheme {
 public:
  HostScheme(std::string_view name, std::unique_ptr<Stencil> stencil)
      : name_(name), stencil_(std::move(stencil)) {}
  std::string_view name() const override { return name_; }
  bool interpolating() const override { return stencil_->interpolating(); }
  std::uint64_t predict_faces(std::uint64_t faces, int levels) const override {
    constexpr std::uint64_t k = Host<Stencil>::kFacesPerFace;
    // Saturates instead of overflowing, so absurd requests still compare as too large.
    for (int i = 0; i < levels; ++i) faces = faces > UINT64_MAX / k ? UINT64_MAX : faces * k;
    return faces;
  }
  Level refine_once(const Level& coarse, StepStats& stats) const override {
    return Host<Stencil>::step(coarse, *stencil_, stats);
  }
  const Stencil& stencil() const { return *stencil_; }

 private:
  std::string_view name_;
  std::unique_ptr<Stencil> stencil_;
};

}  // namespace stlrefine
