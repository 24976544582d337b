// Plain-text particle files: "# key=value" header lines, then one "id x y z diameter" row per
// particle (SI units). This is the format of the peer benchmark's reference packing and of the
// state files crushdem writes for it.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "crushdem/core/types.hpp"

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
};

/// Reads a packing file; throws ConfigError naming the file (and line) on any problem.
Packing read_packing(const std::string& path);
/// Writes rows sorted by id with full double precision.
void write_packing(const std::string& path, const Packing& packing);

}  // namespace crushdem
