#include "crushdem/fracture/pattern.hpp"

#include <cmath>
#include <fstream>
#include <sstream>

#include "crushdem/core/error.hpp"

namespace crushdem {

SplitPattern SplitPattern::default14() {
  SplitPattern p;
  const double deg = kPi / 180.0;
  p.radius = {0.5, 0.5};
  p.position = {{0.0, 0.0, 0.5}, {0.0, 0.0, -0.5}};
  for (int k = 0; k < 6; ++k) {
    const double a = 60.0 * k * deg;
    p.radius.push_back(1.0 / 3.0);
    p.position.push_back({2.0 / 3.0 * std::cos(a), 2.0 / 3.0 * std::sin(a), 0.0});
  }
  const double rho = std::sqrt(0.48);
  const double up[3] = {30.0, 150.0, 270.0}, down[3] = {90.0, 210.0, 330.0};
  for (double a : up) {
    p.radius.push_back(0.2);
    p.position.push_back({rho * std::cos(a * deg), rho * std::sin(a * deg), 0.4});
  }
  for (double a : down) {
    p.radius.push_back(0.2);
    p.position.push_back({rho * std::cos(a * deg), rho * std::sin(a * deg), -0.4});
  }
  return p;
}

SplitPattern SplitPattern::from_file(const std::string& path) {
  std::ifstream f(path);
  if (!f) throw ConfigError("crushing.pattern = \"" + path + "\": cannot open the file");
  SplitPattern p;
  std::string line;
  int no = 0;
  while (std::getline(f, line)) {
    ++no;
    const auto hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    std::istringstream ss(line);
    double r, x, y, z;
    if (!(ss >> r)) continue;  // blank line
    if (!(ss >> x >> y >> z)) {
      throw ConfigError(path + ":" + std::to_string(no) +
                        ": expected 'radius_fraction x y z' (units of the parent radius)");
    }
    p.radius.push_back(r);
    p.position.push_back({x, y, z});
  }
  p.validate("crushing.pattern = \"" + path + "\"");
  return p;
}

void SplitPattern::validate(const std::string& what, double tol) const {
  if (radius.empty()) throw ConfigError(what + ": expected at least one fragment");
  for (std::size_t a = 0; a < radius.size(); ++a) {
    if (!(radius[a] > 0.0 && radius[a] < 1.0)) {
      throw ConfigError(what + ": fragment " + std::to_string(a + 1) + " has radius fraction " +
                        show_number(radius[a]) + ": expected a value in (0, 1)");
    }
    if (norm(position[a]) + radius[a] > 1.0 + tol) {
      throw ConfigError(what + ": fragment " + std::to_string(a + 1) +
                        " reaches outside the parent (|x| + r = " +
                        show_number(norm(position[a]) + radius[a]) + " > 1)");
    }
    for (std::size_t b = 0; b < a; ++b) {
      const double gap = norm(position[a] - position[b]) - radius[a] - radius[b];
      if (gap < -tol) {
        throw ConfigError(what + ": fragments " + std::to_string(b + 1) + " and " +
                          std::to_string(a + 1) + " overlap by " + show_number(-gap) +
                          " parent radii");
      }
    }
  }
}

double SplitPattern::retained_volume_fraction() const {
  double v = 0.0;
  for (double r : radius) v += r * r * r;
  return v;
}

}  // namespace crushdem
