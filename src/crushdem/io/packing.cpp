#include "crushdem/io/packing.hpp"

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <unordered_set>

#include "crushdem/core/error.hpp"
#include "crushdem/particles/generate.hpp"

namespace crushdem {

double Packing::header_number(const std::string& key, const std::string& path) const {
  auto it = header.find(key);
  if (it == header.end()) throw ConfigError(path + ": header has no '# " + key + "=' line");
  char* end = nullptr;
  const double v = std::strtod(it->second.c_str(), &end);
  if (end == it->second.c_str() || !std::isfinite(v)) {
    throw ConfigError(path + ": header " + key + "=" + it->second + ": expected a number");
  }
  return v;
}

std::array<double, kNumWalls> Packing::box(const std::string& path) const {
  std::array<double, kNumWalls> b{};
  for (int k = 0; k < kNumWalls; ++k) {
    b[static_cast<std::size_t>(k)] = header_number(box_header_key(k), path);
  }
  return b;
}

Packing::Chamber Packing::chamber(const std::string& path, const std::string& key) const {
  Chamber c;
  if (!header.count("chamber_radius")) return c;
  c.radius = header_number("chamber_radius", path);
  if (header.count("sector")) {
    c.sector = header_number("sector", path);
  } else if (!rows.empty()) {
    bool x_pos = true, y_pos = true;
    for (const PackingRow& row : rows) {
      x_pos = x_pos && row.position.x > 0.0;
      y_pos = y_pos && row.position.y > 0.0;
    }
    if (x_pos) {
      throw ConfigError(bad_value(key, "\"" + path + "\"",
                                  "a chamber sample file with a '# sector=' line: every grain lies "
                                  "at x > 0 (a half or a quarter of a chamber); add '# sector=" +
                                      std::string(y_pos ? "90" : "180") + "' to its header"));
    }
  }
  return c;
}

Packing read_packing(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw ConfigError("particle file '" + path + "' cannot be opened");
  Packing pk;
  std::string line;
  int lineno = 0;
  std::unordered_set<ParticleId> seen;
  bool ends_with_newline = true;
  while (std::getline(in, line)) {
    ++lineno;
    ends_with_newline = !in.eof();  // getline stopped at a newline, not at the end of the file
    if (line.empty() || line.find_first_not_of(" \t\r") == std::string::npos) continue;
    if (line[0] == '#') {
      const auto eq = line.find('=');
      if (eq != std::string::npos) {
        auto trim = [](const std::string& s) {
          const auto b = s.find_first_not_of(" \t\r");
          const auto e = s.find_last_not_of(" \t\r");
          return b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
        };
        pk.header[trim(line.substr(1, eq - 1))] = trim(line.substr(eq + 1));
      }
      continue;
    }
    std::istringstream s(line);
    PackingRow r;
    long long id = 0;  // signed: "-1" must not wrap round to the no-parent id
    if (!(s >> id >> r.position.x >> r.position.y >> r.position.z >> r.diameter)) {
      throw ConfigError(path + ":" + std::to_string(lineno) +
                        ": expected 'id x y z diameter', got '" + line + "'");
    }
    if (!(s >> std::ws).eof()) {
      throw ConfigError(path + ":" + std::to_string(lineno) +
                        ": expected the 5 columns 'id x y z diameter', got more: '" + line + "'");
    }
    if (id < 0) {
      throw ConfigError(path + ":" + std::to_string(lineno) + ": particle id " +
                        std::to_string(id) + ": expected an id >= 0");
    }
    r.id = static_cast<ParticleId>(id);
    if (!(r.diameter > 0.0) || !std::isfinite(r.position.x) || !std::isfinite(r.position.y) ||
        !std::isfinite(r.position.z)) {
      throw ConfigError(path + ":" + std::to_string(lineno) +
                        ": expected finite coordinates and a positive diameter");
    }
    if (!seen.insert(r.id).second) {
      throw ConfigError(path + ":" + std::to_string(lineno) + ": particle id " +
                        std::to_string(r.id) + " appears twice: expected unique ids");
    }
    pk.rows.push_back(r);
  }
  if (pk.rows.empty()) throw ConfigError("particle file '" + path + "' holds no particles");
  // A file cut short: crushdem's own files say how many grains they hold, and every file's last
  // line ends with a newline (a cut inside a number would otherwise read as a smaller number).
  if (!ends_with_newline) {
    throw ConfigError(path + ":" + std::to_string(lineno) +
                      ": the file ends inside a line (cut short?): expected each line, the last "
                      "included, to end with a newline");
  }
  if (const auto it = pk.header.find(Packing::kCountHeader); it != pk.header.end()) {
    if (it->second != std::to_string(pk.rows.size())) {
      throw ConfigError(path + ": header " + std::string(Packing::kCountHeader) + "=" + it->second +
                        " but the file holds " + std::to_string(pk.rows.size()) +
                        " grains: it was cut short or edited");
    }
  }
  // Two grains at one point, or one deep inside another, would meet with an enormous force at
  // the first step.
  std::vector<PlacedSphere> grains;
  grains.reserve(pk.rows.size());
  for (const PackingRow& r : pk.rows) grains.push_back({r.position, 0.5 * r.diameter});
  if (const auto deep = find_deep_overlap(grains)) {
    const PackingRow &a = pk.rows[deep->a], &b = pk.rows[deep->b];
    const bool same = a.position.x == b.position.x && a.position.y == b.position.y &&
                      a.position.z == b.position.z;
    char share[32];
    std::snprintf(share, sizeof share, "%.0f %%", 100.0 * deep->share);
    throw ConfigError(
        path + ": particles " + std::to_string(a.id) + " and " + std::to_string(b.id) +
        (same ? std::string(" sit at the same point")
              : " overlap by " + std::string(share) + " of the smaller radius") +
        ": expected distinct grains overlapping by at most " +
        std::to_string(static_cast<int>(100.0 * kMaxInputOverlapShare)) + " % of a radius");
  }
  return pk;
}

void write_packing(const std::string& path, const Packing& packing) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (!f) throw ConfigError("cannot write '" + path + "'");
  for (const auto& [k, v] : packing.header) {
    if (k != Packing::kCountHeader) std::fprintf(f, "# %s=%s\n", k.c_str(), v.c_str());
  }
  std::fprintf(f, "# %s=%zu\n", Packing::kCountHeader, packing.rows.size());
  std::vector<const PackingRow*> rows;
  for (const auto& r : packing.rows) rows.push_back(&r);
  std::sort(rows.begin(), rows.end(), [](auto* a, auto* b) { return a->id < b->id; });
  for (const auto* r : rows) {
    std::fprintf(f, "%llu %.17g %.17g %.17g %.17g\n", static_cast<unsigned long long>(r->id),
                 r->position.x, r->position.y, r->position.z, r->diameter);
  }
  if (std::fclose(f) != 0) throw ConfigError("cannot write '" + path + "'");
}

}  // namespace crushdem
