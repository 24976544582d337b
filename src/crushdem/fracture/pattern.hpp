// Splitting patterns (docs/model.md 2.2): a broken grain is replaced by fragments given as data,
// radius fractions and positions in units of the parent radius in a local frame whose e_z is
// turned to the normal of the parent's contact with the largest F_n.
//
// Default (CHOICE, reconstruction of the study's 14 fragments), parent radius R, axis e_z:
//   2 of R/2 at (0, 0, +-R/2);
//   6 of R/3 in the plane z = 0 at 2R/3 from the axis, azimuths 0, 60, ..., 300 deg;
//   6 of R/5 at sqrt(0.48) R from the axis, z = +0.4 R at azimuths 30, 150, 270 deg and
//   z = -0.4 R at 90, 210, 330 deg.
// All inside the parent, touching without overlap, centroid at the centre; 0.520 of the volume.
#pragma once

#include <string>
#include <vector>

#include "crushdem/core/types.hpp"

namespace crushdem {

struct SplitPattern {
  std::vector<double> radius;  // fragment radius / parent radius
  std::vector<Vec3> position;  // fragment centre / parent radius, local frame
  static SplitPattern default14();
  /// Reads "radius_fraction x y z" rows ('#' comments); throws ConfigError naming the file.
  static SplitPattern from_file(const std::string& path);
  /// Every fragment inside the unit sphere and no two overlapping (both to `tol`), at least one
  /// fragment; throws ConfigError naming `what` and the offending fragments.
  void validate(const std::string& what, double tol = 1e-12) const;
  double retained_volume_fraction() const;
  std::size_t size() const { return radius.size(); }
};

}  // namespace crushdem
