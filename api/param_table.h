// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// The one table of request parameters. Each row: the API name, its JSON type, its texts
// (the OpenAPI description and the CLI option help) and, per request kind, how its value is
// read into the request (null: that kind does not take it). The query parser
// (api/params.cpp), the CLI's options and help (cli/main.cpp) and the OpenAPI document
// (server/openapi.cpp) are all made from it, so they cannot drift: a parameter is added by
// adding its row (and, for a scheme option, naming it in the scheme's registry row,
// core/schemes/registry.h). tests/server/param_table_test.cpp checks every row reaches all
// three.

#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "api/params.h"

namespace stlrefine::api {

enum class ParamType { String, Number, Integer };
//! "string", "number", "integer" (the OpenAPI schema type).
const char* to_string(ParamType type);

//! The request kinds: a route of the daemon, a subcommand of the CLI.
enum class RequestKind { Refine, Slice, Info };

struct ParamRow {
  std::string_view name = {};  //!< as in a query string; the CLI option: cli_option(name)
  ParamType type = ParamType::String;
  std::string_view description = {};  //!< the OpenAPI document's
  std::string_view help = {};         //!< the CLI option's
  //! A value every request kind that takes it accepts alone (for the tests).
  std::string_view example = {};
  //! Read by the CLI only (`threads`: the daemon decides threads itself).
  bool cli_only = false;
  //! How a value is read into each request kind; null where the kind does not take it.
  //! \throw Error(InvalidParameter) naming the field.
  void (*refine)(RefineRequest&, const std::string& value, const RequestLimits&) = nullptr;
  void (*slice)(SliceRequest&, const std::string& value) = nullptr;
  void (*info)(InfoRequest&, const std::string& value) = nullptr;

  bool takes(RequestKind kind) const;
};

//! Every parameter, in a stable order (the order the name lists, the OpenAPI document and
//! the CLI's help show them in).
std::span<const ParamRow> param_table();

//! The row of `name`, or null.
const ParamRow* find_param(std::string_view name);

//! The schemes whose registry row names `name` among their options; empty for a parameter
//! every scheme reads.
std::vector<std::string_view> schemes_using(std::string_view name);

//! "crease_angle" -> "--crease-angle".
std::string cli_option(std::string_view name);

}  // namespace stlrefine::api
