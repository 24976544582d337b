#include "crushdem/contact/power_table.hpp"

#include <map>
#include <mutex>
#include <vector>

namespace crushdem {

PowerTable power_table(double p) {
  constexpr int kIntervals = 2048;
  static std::mutex mutex;
  static std::map<double, std::vector<double>> tables;  // node storage never moves
  std::lock_guard<std::mutex> lock(mutex);
  auto it = tables.find(p);
  if (it == tables.end()) {
    std::vector<double> v(2 * (kIntervals + 1));
    const double h = 1.0 / kIntervals;
    for (int k = 0; k <= kIntervals; ++k) {
      const double x = k * h;
      v[static_cast<std::size_t>(2 * k)] = std::pow(x, p);
      v[static_cast<std::size_t>(2 * k + 1)] = x > 0.0 ? p * std::pow(x, p - 1.0) * h : 0.0;
    }
    it = tables.emplace(p, std::move(v)).first;
  }
  return PowerTable{it->second.data(), kIntervals, static_cast<double>(kIntervals), p};
}

}  // namespace crushdem
