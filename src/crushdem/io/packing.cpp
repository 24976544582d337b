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

Packing read_packing(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw ConfigError("particle file '" + path + "' cannot be opened");
  Packing pk;
  std::string line;
  int lineno = 0;
  std::unordered_set<ParticleId> seen;
  while (std::getline(in, line)) {
    ++lineno;
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
  // Two grains at one point would meet with an infinite force at the first step.
  std::vector<std::size_t> order(pk.rows.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  const auto at = [&](std::size_t i) {
    const Vec3& x = pk.rows[i].position;
    return std::array<double, 3>{x.x, x.y, x.z};
  };
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return at(a) < at(b); });
  for (std::size_t k = 1; k < order.size(); ++k) {
    if (at(order[k]) == at(order[k - 1])) {
      throw ConfigError(path + ": particles " + std::to_string(pk.rows[order[k - 1]].id) + " and " +
                        std::to_string(pk.rows[order[k]].id) +
                        " sit at the same point: expected distinct positions");
    }
  }
  return pk;
}

void write_packing(const std::string& path, const Packing& packing) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (!f) throw ConfigError("cannot write '" + path + "'");
  for (const auto& [k, v] : packing.header) std::fprintf(f, "# %s=%s\n", k.c_str(), v.c_str());
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
