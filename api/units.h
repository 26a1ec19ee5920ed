// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Units of a part (issue 19 item 1). STL carries no unit; everything downstream (layer
// heights, tolerances, deviations, the CLI format's $$UNITS/1) reads millimetres. A part
// exported in metres is 1000x too small and slices to nothing; a part whose size is not
// plausible in mm is flagged, and converted only when the caller says what it is in.

#include <optional>
#include <string>
#include <string_view>

#include "core/geometry/vec3.h"
#include "core/mesh/mesh.h"

namespace stlrefine::api {

//! Micrometre and Foot come only from a 3MF's declared unit (not values of `units`).
enum class LengthUnit { Auto, Millimetre, Centimetre, Metre, Inch, Micrometre, Foot };

//! `units` and `scale` of a request.
struct UnitOptions {
  //! `units`: what the file's numbers are in; `auto` (default) assumes mm and flags a part
  //! whose size is implausible for mm, without converting it.
  LengthUnit units = LengthUnit::Auto;
  //! `scale`: multiplies the part (after the unit conversion), (0, 1e6]; default 1.
  double scale = 1.0;
};

//! "auto", "mm", "cm", "m", "in" -> the unit. \throw Error(InvalidParameter, field "units").
LengthUnit parse_length_unit(std::string_view text);
const char* to_string(LengthUnit unit);

//! Parts smaller than this in every direction, or larger in one, are implausible in mm.
inline constexpr double kSmallestPlausibleMm = 1.0;
inline constexpr double kLargestPlausibleMm = 2000.0;

//! What was assumed and done, for the report.
struct UnitsReport {
  LengthUnit units = LengthUnit::Millimetre;  //!< the units the input was read in
  bool assumed = true;                        //!< `auto`: mm assumed, not given
  double scale = 1.0;                         //!< the `scale` applied
  double factor = 1.0;                        //!< input number -> output mm
  Vec3 size_mm;                               //!< the part's extents in mm, after conversion
  //! The unit the file declares (a 3MF's "micron" ... "meter"): it is the one applied,
  //! whatever `units` says.
  std::optional<std::string> declared;
  //! Set when the size is implausible for mm: says why and what to give instead; also
  //! when `units` disagrees with the unit the file declares.
  std::optional<std::string> warning;
};

//! Converts `mesh` to mm (multiplies every position by the unit's factor times `scale`;
//! nothing when that is 1) and checks the result's size.
UnitsReport apply_units(Mesh& mesh, const UnitOptions& options);

//! The same for a file that declares its unit (3MF: `declared_name`, `declared_mm` mm per
//! unit): that unit is authoritative (converted without `units=`, reported); a `units`
//! that says otherwise is ignored with a warning. `scale` applies as always.
UnitsReport apply_units(Mesh& mesh, const UnitOptions& options, const std::string& declared_name,
                        double declared_mm);

}  // namespace stlrefine::api
