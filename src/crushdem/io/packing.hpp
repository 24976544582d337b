// Plain-text particle files: "# key=value" header lines, then one "id x y z diameter" row per
// particle (SI units). This is the format of the peer benchmark's reference packing and of the
// state files crushdem writes for it.
#pragma once

#include <array>
#include <map>
#include <string>
#include <vector>

#include "crushdem/core/types.hpp"
#include "crushdem/walls/walls.hpp"

namespace crushdem {

struct PackingRow {
  ParticleId id = 0;
  Vec3 position;
  double diameter = 0.0;
};

struct Packing {
  std::map<std::string, std::string> header;
  std::vector<PackingRow> rows;
  /// A header value as a number; throws ConfigError naming the file and key when absent or bad.
  double header_number(const std::string& key, const std::string& path) const;
  /// Whether the file carries a prepared sample's box ('# box_xmin=' ... '# box_zmax=').
  bool has_box() const { return header.count(box_header_key(0)) != 0; }
  /// The six wall positions of that box, in wall order; throws like header_number.
  std::array<double, kNumWalls> box(const std::string& path) const;
  /// The header key of wall k's position ("box_xmin" ... "box_zmax").
  static std::string box_header_key(int k) { return std::string("box_") + wall_name(k); }
  /// The header key of the number of grains (written by crushdem; checked when present, so a
  /// file cut at a line end is refused).
  static constexpr const char* kCountHeader = "particles";
  /// The chamber a chamber sample was prepared in ('# chamber_radius=', '# sector='): radius 0
  /// for any other file. A file whose grains all lie at x > 0 but that records no sector (a half
  /// or a quarter written before sample files carried it) is refused with a ConfigError naming
  /// `key` and the file: read as a whole chamber, its grains would spread into the empty part.
  struct Chamber {
    double radius = 0.0;    // [m]
    double sector = 360.0;  // [deg]
  };
  Chamber chamber(const std::string& path, const std::string& key) const;
};

/// Reads a packing file; throws ConfigError naming the file (and line) on any problem: a bad
/// row, a repeated id, a file cut short (a last line without its newline, or fewer grains than
/// its `# particles=` header says), or two grains at one point or overlapping by more than
/// kMaxInputOverlapShare of the smaller radius.
Packing read_packing(const std::string& path);
/// Writes rows sorted by id with full double precision.
void write_packing(const std::string& path, const Packing& packing);

}  // namespace crushdem
