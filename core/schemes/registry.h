// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// The one table of schemes: name -> factory, the options each one reads (declared here, with
// their types, defaults, ranges and texts: api/param_table.h makes the query parameters, CLI
// options and OpenAPI entries from them), and the base a spectral scheme modifies. No static
// self-registration. Adding a scheme: its stencil file and one row in registry.cpp, with the
// declarations of its options (docs/architecture.md).

#include <memory>
#include <span>
#include <string_view>
#include <vector>

#include "core/schemes/scheme.h"
#include "core/schemes/scheme_options.h"

namespace stlrefine {

class Split4Stencil;

//! One row of the registry.
struct SchemeEntry {
  std::string_view name;
  //! Called with a value for every option in `options` (make_scheme fills in defaults).
  std::unique_ptr<Scheme> (*make)(const SchemeOptions&);
  //! The options it reads. Two schemes reading an option of the same name declare it alike.
  std::span<const SchemeOptionSpec> options = {};
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

//! The declaration of the option `name` (the first scheme's that reads it), or null.
const SchemeOptionSpec* find_scheme_option(std::string_view name);

//! Every option's declaration once, in the registry's order.
std::vector<const SchemeOptionSpec*> scheme_option_specs();

//! Every value of `options` is some scheme's option and inside its range. Values a scheme
//! does not read are allowed (and ignored by it), as a request may name any scheme.
//! \throw Error(InvalidParameter, "unknown_parameter" | "out_of_range" | "not_a_number")
//! naming the option.
void validate_scheme_options(const SchemeOptions& options);

//! Makes `name` with `options` (validated; the options it reads and were not given at their
//! defaults). \throw Error(InvalidParameter, field "scheme") for an unknown name, or as
//! validate_scheme_options.
std::unique_ptr<Scheme> make_scheme(std::string_view name, const SchemeOptions& options = {});

}  // namespace stlrefine
