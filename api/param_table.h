// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// The one table of request parameters. Each row: the API name, its JSON type, its texts
// (the OpenAPI description and the CLI option help) and, per request kind, how its value is
// read into the request (null: that kind does not take it). The query parser
// (api/params.cpp), the CLI's options and help (cli/main.cpp) and the OpenAPI document
// (server/openapi.cpp) are all made from it, so they cannot drift: a parameter is added by
// adding its row. A scheme's options are declared in the scheme's registry row
// (core/schemes/registry.cpp, with their type, default and range) and become rows here by
// themselves. tests/server/param_table_test.cpp checks every row reaches all three users and
// that each row's range is the one its reader enforces.

#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "api/params.h"
#include "core/schemes/scheme_options.h"

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
  std::string_view help = {};         //!< the CLI option's (cli_help adds range and default)
  //! A value every request kind that takes it accepts alone (for the tests).
  std::string_view example = {};
  //! The default as a value of the parameter ("butterfly", "1", "auto"); empty where it
  //! depends on the part or the server (`z_min`, `max_faces`): the texts say.
  std::string_view default_value = {};
  //! The numeric range where there is one, [minimum, maximum] (minimum excluded with
  //! exclusive_minimum), as the reader enforces it (core's or the slicer's validate, or the
  //! row's own reader; param_table_test checks both ends against it).
  std::optional<double> minimum = {}, maximum = {};
  bool exclusive_minimum = false;
  //! Read by the CLI only (`threads`: the daemon decides threads itself).
  bool cli_only = false;
  //! Read by the daemon only (`report`: the CLI writes its report with --report FILE).
  bool http_only = false;
  //! A scheme's option (declared in its registry row): read into
  //! RefineParams::scheme_options; `refine` is then null.
  const SchemeOptionSpec* scheme_option = nullptr;
  //! How a value is read into each request kind; null where the kind does not take it.
  //! \throw Error(InvalidParameter) naming the field.
  void (*refine)(RefineRequest&, const std::string& value, const RequestLimits&) = nullptr;
  void (*slice)(SliceRequest&, const std::string& value) = nullptr;
  void (*info)(InfoRequest&, const std::string& value) = nullptr;

  bool takes(RequestKind kind) const;
};

//! Every parameter (the scheme options last, in the registry's order), in a stable order (the order
//! the name lists, the OpenAPI document and the CLI's help show them in).
std::span<const ParamRow> param_table();

//! The name that replaces `name` on routes of `kind` when `name` is an old name kept for
//! scripts written before every route took the same names (`slice` on /v1/refine is
//! `layer_height`, `format` on /v1/slice is `slice_format`); empty otherwise.
std::string_view replaced_by(RequestKind kind, std::string_view name);

//! The row of `name`, or null.
const ParamRow* find_param(std::string_view name);

//! The schemes whose registry row names `name` among their options; empty for a parameter
//! every scheme reads.
std::vector<std::string_view> schemes_using(std::string_view name);

//! The CLI option's help: the row's help, its range and its default ("... [0, 8] (1)").
std::string cli_help(const ParamRow& row);

//! The default as a value ("1", "auto"); empty when it depends on the part or the server.
std::string default_text(const ParamRow& row);

//! "[0, 8]", "(0, 1]", ">= 0", "<= 8"; empty without a range.
std::string range_text(const ParamRow& row);

//! "crease_angle" -> "--crease-angle".
std::string cli_option(std::string_view name);

}  // namespace stlrefine::api
