// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/scheme_options.h"

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "core/error.h"

namespace stlrefine {

namespace {

// Shortest text that reads back as `value` ("0.5", "1", "1e-06").
std::string number_text(double value) {
  std::ostringstream out;
  out << value;
  return out.str();
}

}  // namespace

std::string SchemeOptionSpec::range_text() const {
  // Built with push_back / append: GCC 12's -Wrestrict misfires on short string literals.
  std::string text(1, exclusive_minimum ? '(' : '[');
  text.append(number_text(minimum)).append(", ").append(number_text(maximum));
  text.push_back(']');
  return text;
}

void SchemeOptionSpec::check(double value) const {
  const std::string field(name);
  if (!std::isfinite(value) || (integer && value != std::floor(value)))
    throw Error(ErrorCode::InvalidParameter, "not_a_number",
                field + " = " + number_text(value) + " is not " +
                    (integer ? "an integer" : "a finite number"))
        .with_field(field);
  const bool above_minimum = exclusive_minimum ? value > minimum : value >= minimum;
  if (!above_minimum || value > maximum)
    throw Error(ErrorCode::InvalidParameter, "out_of_range",
                field + " = " + number_text(value) + " is outside " + range_text())
        .with_field(field);
}

SchemeOptions::SchemeOptions(std::initializer_list<std::pair<std::string_view, double>> values) {
  for (const auto& [name, value] : values) set(name, value);
}

SchemeOptions& SchemeOptions::set(std::string_view name, double value) {
  for (auto& [n, v] : values_)
    if (n == name) {
      v = value;
      return *this;
    }
  values_.emplace_back(std::string(name), value);
  return *this;
}

std::optional<double> SchemeOptions::find(std::string_view name) const {
  for (const auto& [n, v] : values_)
    if (n == name) return v;
  return std::nullopt;
}

double SchemeOptions::get(std::string_view name) const {
  if (const std::optional<double> value = find(name)) return *value;
  throw std::logic_error("scheme option '" + std::string(name) + "' has no value");
}

}  // namespace stlrefine
