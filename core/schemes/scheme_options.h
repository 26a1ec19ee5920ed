// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// The options a scheme reads (sqrt3-unified's alpha, loop-g2's kappa, ...): each is declared
// once, in its scheme's registry row (registry.cpp), with its type, default, range and texts.
// That row is the parameter's row: api/param_table.h makes the query parameter, the CLI
// option and the OpenAPI entry from it, and make_scheme validates values against it. A
// request carries the values it was given by name; the scheme is made with every option it
// reads, the missing ones at their defaults.

#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace stlrefine {

//! One option of a scheme: the declaration every user of it reads.
struct SchemeOptionSpec {
  std::string_view name;  //!< the parameter's name ("alpha"); the CLI option "--alpha"
  bool integer = false;   //!< an integer (read as one; JSON "integer")
  double default_value = 0;
  double minimum = 0, maximum = 0;  //!< the range, both ends included ...
  bool exclusive_minimum = false;   //!< ... unless this: (minimum, maximum]
  std::string_view description;     //!< the OpenAPI document's (the range is added)
  std::string_view help;            //!< the CLI option's (the range and default are added)
  std::string_view example;         //!< a value inside the range (for the tests)

  //! "[0, 1]", "(0, 1]".
  std::string range_text() const;
  //! \throw Error(InvalidParameter, "out_of_range" | "not_a_number") naming the option.
  void check(double value) const;
};

//! Option values by name. A request's hold what it was given; the options a scheme is made
//! with hold every option it reads (make_scheme fills in the defaults).
class SchemeOptions {
 public:
  SchemeOptions() = default;
  SchemeOptions(std::initializer_list<std::pair<std::string_view, double>> values);

  //! Sets (or replaces) the value of `name`.
  SchemeOptions& set(std::string_view name, double value);
  //! The value of `name`, if it has one.
  std::optional<double> find(std::string_view name) const;
  //! The value of `name`; inside a factory every option of the scheme has one.
  //! \throw std::logic_error when it has none (a registry row naming an undeclared option).
  double get(std::string_view name) const;

  bool empty() const { return values_.empty(); }
  const std::vector<std::pair<std::string, double>>& values() const { return values_; }

 private:
  std::vector<std::pair<std::string, double>> values_;
};

}  // namespace stlrefine
