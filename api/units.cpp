// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "api/units.h"

#include <algorithm>
#include <cstdio>

#include "core/error.h"

namespace stlrefine::api {

namespace {

struct UnitRow {
  LengthUnit unit;
  const char* name;
  double mm;          // one unit in mm
  bool given = true;  // a value of `units` (else only a file's declared unit)
};

constexpr UnitRow kUnits[] = {
    {LengthUnit::Auto, "auto", 1.0},        {LengthUnit::Millimetre, "mm", 1.0},
    {LengthUnit::Centimetre, "cm", 10.0},   {LengthUnit::Metre, "m", 1000.0},
    {LengthUnit::Inch, "in", 25.4},         {LengthUnit::Micrometre, "um", 0.001, false},
    {LengthUnit::Foot, "ft", 304.8, false},
};

const UnitRow& row_of(LengthUnit unit) {
  for (const UnitRow& row : kUnits)
    if (row.unit == unit) return row;
  return kUnits[0];
}

std::string num(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.4g", v);
  return text;
}

std::string size_text(const Vec3& s) {
  return num(s.x) + " x " + num(s.y) + " x " + num(s.z) + " mm";
}

// The unit that makes a part of largest extent `largest` (read as mm) plausible, if one does.
std::optional<LengthUnit> likely_unit(double largest) {
  for (LengthUnit unit : {LengthUnit::Metre, LengthUnit::Inch, LengthUnit::Centimetre}) {
    const double converted = largest * row_of(unit).mm;
    if (converted >= 10 * kSmallestPlausibleMm && converted <= kLargestPlausibleMm) return unit;
  }
  return std::nullopt;
}

}  // namespace

LengthUnit parse_length_unit(std::string_view text) {
  for (const UnitRow& row : kUnits)
    if (row.given && text == row.name) return row.unit;
  throw Error(ErrorCode::InvalidParameter, "unknown_value",
              "units = '" + std::string(text.substr(0, 64)) + "' is not one of auto, mm, cm, m, in")
      .with_field("units");
}

const char* to_string(LengthUnit unit) {
  return row_of(unit).name;
}

namespace {

// Scales the mesh by report.factor and fills in the size and the plausibility warning;
// `given` says how the numbers were read, for the message.
void convert_and_check(Mesh& mesh, UnitsReport& report, const std::string& given) {
  if (report.factor != 1.0)
    for (Vec3& p : mesh.mutable_positions()) p = p * report.factor;

  Vec3 lo = mesh.num_vertices() ? mesh.position(VertexId(0)) : Vec3{};
  Vec3 hi = lo;
  for (const Vec3& p : mesh.positions()) {
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
  }
  report.size_mm = hi - lo;
  const double largest = std::max({report.size_mm.x, report.size_mm.y, report.size_mm.z});
  if (largest < kSmallestPlausibleMm) {
    std::string what = "the part is " + size_text(report.size_mm) + " " + given +
                       ": every extent is under " + num(kSmallestPlausibleMm) + " mm";
    const std::optional<LengthUnit> unit =
        report.assumed ? likely_unit(largest) : std::optional<LengthUnit>{};
    if (unit)
      what += "; if it was exported in " + std::string(to_string(*unit)) +
              ", give units=" + to_string(*unit) + " (" +
              size_text(report.size_mm * row_of(*unit).mm) + ")";
    else
      what += "; give units= or scale= to make it its real size";
    report.warning = what;
  } else if (largest > kLargestPlausibleMm) {
    report.warning = "the part is " + size_text(report.size_mm) + " " + given + ": over " +
                     num(kLargestPlausibleMm / 1000) +
                     " m across; if its numbers are not mm, give units= or scale=";
  }
}

}  // namespace

UnitsReport apply_units(Mesh& mesh, const UnitOptions& options) {
  UnitsReport report;
  report.assumed = options.units == LengthUnit::Auto;
  report.units = report.assumed ? LengthUnit::Millimetre : options.units;
  report.scale = options.scale;
  report.factor = row_of(report.units).mm * options.scale;
  convert_and_check(mesh, report,
                    report.assumed ? std::string("read as mm (units=auto)")
                                   : std::string("in mm after units=") + to_string(report.units) +
                                         (options.scale != 1 ? " and scale" : ""));
  return report;
}

UnitsReport apply_units(Mesh& mesh, const UnitOptions& options, const std::string& declared_name,
                        double declared_mm) {
  UnitsReport report;
  report.assumed = false;
  report.declared = declared_name;
  report.units = LengthUnit::Millimetre;
  for (const UnitRow& row : kUnits)
    if (row.unit != LengthUnit::Auto && row.mm == declared_mm) report.units = row.unit;
  report.scale = options.scale;
  report.factor = declared_mm * options.scale;
  convert_and_check(mesh, report,
                    "in mm after the file's unit (" + declared_name + ")" +
                        (options.scale != 1 ? " and scale" : ""));
  if (options.units != LengthUnit::Auto && options.units != report.units) {
    const std::string ignored = std::string("units=") + to_string(options.units) +
                                " is ignored: the file declares its unit, " + declared_name;
    report.warning = report.warning ? ignored + "; " + *report.warning : ignored;
  }
  return report;
}

}  // namespace stlrefine::api
