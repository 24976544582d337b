#include "crushdem/contact/power_table.hpp"

#include <map>
#include <mutex>
#include <vector>

namespace crushdem {

namespace {

constexpr int kIntervals = 2048;

// Nodes of x^p at k h, k = 0..n: the value and the derivative times h.
void fill_nodes(double p, double* v) {
  const double h = 1.0 / kIntervals;
  for (int k = 0; k <= kIntervals; ++k) {
    const double x = k * h;
    v[2 * k] = std::pow(x, p);
    v[2 * k + 1] = x > 0.0 ? p * std::pow(x, p - 1.0) * h : 0.0;
  }
}

std::mutex mutex;
std::map<std::pair<double, double>, std::vector<double>> tables;  // node storage never moves

// The block for exponents (p1, p2): both tables, the second after the first.
const double* nodes_for(double p1, double p2) {
  std::lock_guard<std::mutex> lock(mutex);
  auto it = tables.find({p1, p2});
  if (it == tables.end()) {
    std::vector<double> v(4 * (kIntervals + 1));
    fill_nodes(p1, v.data());
    fill_nodes(p2, v.data() + 2 * (kIntervals + 1));
    it = tables.emplace(std::make_pair(p1, p2), std::move(v)).first;
  }
  return it->second.data();
}

PowerTable view(const double* nodes, double p) {
  return PowerTable{nodes, kIntervals, static_cast<double>(kIntervals), p};
}

}  // namespace

std::array<PowerTable, 2> power_table_pair(double p1, double p2) {
  const double* nodes = nodes_for(p1, p2);
  return {view(nodes, p1), view(nodes + 2 * (kIntervals + 1), p2)};
}

}  // namespace crushdem
