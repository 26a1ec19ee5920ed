// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// The one table of schemes: name -> factory, the options each one reads, and the base a
// spectral scheme modifies. No static self-registration. Adding a scheme: its stencil file,
// one row in registry.cpp, and the rows of its parameters in the parameter table
// (api/param_table.h).

#include <memory>
#include <span>
#include <string_view>

#include "core/schemes/scheme.h"

namespace stlrefine {

class Split4Stencil;

//! Parameters some schemes take; every scheme ignores the ones it has no use for.
struct SchemeOptions {
  //! sqrt3-unified: alpha of smooth (and dart) input vertices, [0, 1]; 1 interpolates.
  double alpha = 1.0;
  //! sqrt3-unified: alpha of crease and corner input vertices (boundaries included), [0, 1].
  double alpha_features = 1.0;
  //! loop-g2: the moved eigenvalues go to kappa lambda^2, (0, 1] (spec 6, recommended 0.5).
  double kappa = 0.5;
  //! loop-g2: Remark 5.3's gradual modification over this many steps, [0, 8]; 0 = off.
  int ramp_steps = 0;
};

//! One row of the registry.
struct SchemeEntry {
  std::string_view name;
  std::unique_ptr<Scheme> (*make)(const SchemeOptions&);
  //! The SchemeOptions it reads, by their parameter names ("alpha", "kappa", ...).
  std::span<const std::string_view> options = {};
  //! Spectral schemes (loop-g2, butterfly-g1): the stencil they modify, analysed on its own
  //! by `stlrefine spectrum --unmodified`; null for the others.
  std::unique_ptr<Split4Stencil> (*base)() = nullptr;
};

//! Every scheme, in a stable order ("butterfly", "loop", ...).
std::span<const SchemeEntry> scheme_registry();

//! The row of `name`, or null.
const SchemeEntry* find_scheme(std::string_view name);

//! Names accepted by make_scheme, in the registry's order.
std::span<const std::string_view> scheme_names();

//! \throw Error(InvalidParameter, field "scheme") for an unknown name.
std::unique_ptr<Scheme> make_scheme(std::string_view name, const SchemeOptions& options = {});

}  // namespace stlrefine
