#include "crushdem/neighbor/neighbor_list.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <numeric>
#include <stdexcept>

#include "crushdem/core/deterministic.hpp"

namespace crushdem {
namespace {

constexpr int kMaxLevels = 12;

struct Bounds {
  double lo[3], hi[3];
};

Bounds particle_bounds(const ParticleStore& p) {
  Bounds b{};
  for (int d = 0; d < 3; ++d) {
    b.lo[d] = std::numeric_limits<double>::max();
    b.hi[d] = -std::numeric_limits<double>::max();
  }
  const double* c[3] = {p.x.data(), p.y.data(), p.z.data()};
  for (std::size_t i = 0; i < p.size(); ++i) {
    for (int d = 0; d < 3; ++d) {
      b.lo[d] = std::min(b.lo[d], c[d][i] - p.radius[i]);
      b.hi[d] = std::max(b.hi[d], c[d][i] + p.radius[i]);
    }
  }
  return b;
}

// One level of the grid: cells of side `h` over the particle bounds, counting-sorted.
struct Level {
  double r_max = 0.0;  // largest radius this level may hold
  double h = 0.0;      // cell side
  long n[3] = {0, 0, 0};
  std::vector<std::uint32_t> cell_start;  // size ncells + 1
  std::vector<std::uint32_t> members;     // particle indices, sorted by cell then index

  long cell_coord(double v, double lo, int d) const {
    long c = static_cast<long>(std::floor((v - lo) / h));
    return std::clamp(c, 0L, n[d] - 1);
  }
};

// Side of the scatter columns: the largest pair reach 2 r_max + skin, widened by a relative 1e-12
// so that two grains closer than the reach can never round into columns two apart.
double column_side(double r_max, double skin) {
  return (2.0 * r_max + skin) * (1.0 + 1e-12);
}

int level_of(double r, double r_max, int nlevels) {
  // level L holds r in (r_max / 2^(L+1), r_max / 2^L]
  int L = 0;
  double bound = r_max * 0.5;
  while (L + 1 < nlevels && r <= bound) {
    ++L;
    bound *= 0.5;
  }
  return L;
}

}  // namespace

void NeighborList::build(const ParticleStore& p, double skin) {
  if (!(skin > 0.0)) throw std::invalid_argument("neighbour skin must be positive");
  skin_ = skin;
  ++builds_;
  const std::size_t N = p.size();
  if (N > std::numeric_limits<Index>::max() / 2) throw std::length_error("too many particles");
  x0_ = p.x;
  y0_ = p.y;
  z0_ = p.z;
  offsets.assign(N + 1, 0);
  neighbors.clear();
  owner.clear();
  column_offsets.assign(1, 0);
  column_members.clear();
  color_offsets.assign(kColors + 1, 0);
  column_work.assign(1, 0);
  if (N == 0) return;

  const Bounds B = particle_bounds(p);
  const double r_max = *std::max_element(p.radius.begin(), p.radius.end());
  const double r_min = *std::min_element(p.radius.begin(), p.radius.end());
  int nlevels = 1;
  while (nlevels < kMaxLevels && r_max / std::ldexp(1.0, nlevels) >= r_min) ++nlevels;

  std::vector<int> level(N);
  for (std::size_t i = 0; i < N; ++i) level[i] = level_of(p.radius[i], r_max, nlevels);

  std::vector<Level> levels(static_cast<std::size_t>(nlevels));
  std::vector<long> cell_of(N);
  const double* c[3] = {p.x.data(), p.y.data(), p.z.data()};
  for (int L = 0; L < nlevels; ++L) {
    Level& lv = levels[static_cast<std::size_t>(L)];
    lv.r_max = std::ldexp(r_max, -L);
    lv.h = 2.0 * lv.r_max + skin;
    long ncells = 1;
    for (int d = 0; d < 3; ++d) {
      lv.n[d] = std::max(1L, static_cast<long>(std::ceil((B.hi[d] - B.lo[d]) / lv.h)));
      ncells *= lv.n[d];
    }
    // Very fine levels over a large domain would need huge arrays: cap by coarsening the cells
    // (correct, only slower), since a level never holds more cells than needed.
    while (ncells > 64L * static_cast<long>(N) + 4096) {
      lv.h *= 2.0;
      ncells = 1;
      for (int d = 0; d < 3; ++d) {
        lv.n[d] = std::max(1L, static_cast<long>(std::ceil((B.hi[d] - B.lo[d]) / lv.h)));
        ncells *= lv.n[d];
      }
    }
    lv.cell_start.assign(static_cast<std::size_t>(ncells) + 1, 0);
  }
  for (std::size_t i = 0; i < N; ++i) {
    Level& lv = levels[static_cast<std::size_t>(level[i])];
    long cc[3];
    for (int d = 0; d < 3; ++d) cc[d] = lv.cell_coord(c[d][i], B.lo[d], d);
    cell_of[i] = (cc[2] * lv.n[1] + cc[1]) * lv.n[0] + cc[0];
    ++lv.cell_start[static_cast<std::size_t>(cell_of[i]) + 1];
  }
  for (Level& lv : levels) {
    std::partial_sum(lv.cell_start.begin(), lv.cell_start.end(), lv.cell_start.begin());
    lv.members.resize(lv.cell_start.back());
  }
  {
    std::vector<std::vector<std::uint32_t>> fill(levels.size());
    for (std::size_t L = 0; L < levels.size(); ++L) {
      fill[L].assign(levels[L].cell_start.begin(), levels[L].cell_start.end() - 1);
    }
    for (std::size_t i = 0; i < N; ++i) {
      const auto L = static_cast<std::size_t>(level[i]);
      levels[L].members[fill[L][static_cast<std::size_t>(cell_of[i])]++] =
          static_cast<std::uint32_t>(i);
    }
  }

  // Query: two passes (count, then fill) so the CSR is built in parallel without locks, and the
  // order inside each list is fixed by the cell traversal (deterministic).
  auto visit = [&](std::size_t i, auto&& emit) {
    const double xi = p.x[i], yi = p.y[i], zi = p.z[i], ri = p.radius[i];
    const int Li = level[i];
    for (int L = 0; L <= Li; ++L) {
      const Level& lv = levels[static_cast<std::size_t>(L)];
      if (lv.members.empty()) continue;
      const double reach = ri + lv.r_max + skin;
      long lo[3], hi[3];
      const double pos[3] = {xi, yi, zi};
      for (int d = 0; d < 3; ++d) {
        lo[d] = lv.cell_coord(pos[d] - reach, B.lo[d], d);
        hi[d] = lv.cell_coord(pos[d] + reach, B.lo[d], d);
      }
      for (long cz = lo[2]; cz <= hi[2]; ++cz) {
        for (long cy = lo[1]; cy <= hi[1]; ++cy) {
          const long row = (cz * lv.n[1] + cy) * lv.n[0];
          const std::uint32_t b = lv.cell_start[static_cast<std::size_t>(row + lo[0])];
          const std::uint32_t e = lv.cell_start[static_cast<std::size_t>(row + hi[0] + 1)];
          for (std::uint32_t k = b; k < e; ++k) {
            const std::uint32_t j = lv.members[k];
            if (L == Li && j <= i) continue;  // same level: owned by the lower index
            const double dx = p.x[j] - xi, dy = p.y[j] - yi, dz = p.z[j] - zi;
            const double cut = ri + p.radius[j] + skin;
            if (dx * dx + dy * dy + dz * dz < cut * cut) emit(j);
          }
        }
      }
    }
  };

  std::vector<Index> count(N, 0);
#pragma omp parallel for schedule(dynamic, 256) if (worth_threading(N))
  for (std::ptrdiff_t ii = 0; ii < static_cast<std::ptrdiff_t>(N); ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    Index n = 0;
    visit(i, [&](std::uint32_t) { ++n; });
    count[i] = n;
  }
  std::uint64_t total = 0;
  for (std::size_t i = 0; i < N; ++i) total += count[i];
  if (total > std::numeric_limits<Index>::max()) {
    throw std::length_error("neighbour list: more than 2^32 pairs; reduce the skin or the sample");
  }
  for (std::size_t i = 0; i < N; ++i) offsets[i + 1] = offsets[i] + count[i];
  neighbors.resize(offsets[N]);
  owner.resize(offsets[N]);
#pragma omp parallel for schedule(dynamic, 256) if (worth_threading(N))
  for (std::ptrdiff_t ii = 0; ii < static_cast<std::ptrdiff_t>(N); ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    Index w = offsets[i];
    visit(i, [&](std::uint32_t j) {
      owner[w] = static_cast<Index>(i);
      neighbors[w++] = j;
    });
    // Sort each list by partner index: memory access in increasing order, and a canonical order.
    std::sort(neighbors.begin() + offsets[i], neighbors.begin() + offsets[i + 1]);
  }

  build_columns(p, B.lo, column_side(r_max, skin));
  sum_column_work();
}

void NeighborList::sum_column_work() {
  const std::size_t ncols = column_offsets.empty() ? 0 : column_offsets.size() - 1;
  column_work.assign(ncols + 1, 0);
  for (std::size_t c = 0; c < ncols; ++c) {
    std::uint64_t w = 0;
    for (auto k = column_offsets[c]; k < column_offsets[c + 1]; ++k) {
      const Index i = column_members[k];
      w += 1 + offsets[i + 1] - offsets[i];
    }
    column_work[c + 1] = column_work[c] + w;
  }
}

void NeighborList::build_columns(const ParticleStore& p, const double lo[3], double h) {
  // Column (cy, cz) of side h >= the largest pair reach, coloured (cy mod 3, cz mod 3). Only
  // occupied columns are stored (sorting keys, not a dense grid), so a sparse sample in a large
  // box costs memory in proportion to its grains.
  const std::size_t N = p.size();
  std::vector<std::pair<std::uint64_t, Index>> key(N);
  for (std::size_t i = 0; i < N; ++i) {
    const auto cy = static_cast<std::uint64_t>(std::floor((p.y[i] - lo[1]) / h));
    const auto cz = static_cast<std::uint64_t>(std::floor((p.z[i] - lo[2]) / h));
    const std::uint64_t color = (cz % 3) * 3 + (cy % 3);
    key[i] = {(color << 56) | (cz << 28) | cy, static_cast<Index>(i)};
  }
  parallel_stable_sort(key, std::less<>());  // by colour, cz, cy, then particle index
  column_offsets.assign(1, 0);
  color_offsets.assign(kColors + 1, 0);
  column_members.resize(N);
  for (std::size_t k = 0; k < N; ++k) {
    column_members[k] = key[k].second;
    if (k > 0 && key[k].first != key[k - 1].first) column_offsets.push_back(static_cast<Index>(k));
    if (k == 0 || key[k].first != key[k - 1].first) {
      const auto color = static_cast<std::size_t>(key[k].first >> 56);
      for (std::size_t c = color + 1; c <= kColors; ++c) ++color_offsets[c];
    }
  }
  if (N > 0) column_offsets.push_back(static_cast<Index>(N));
}

double NeighborList::max_displacement(const ParticleStore& p) const {
  if (x0_.size() != p.size()) return std::numeric_limits<double>::infinity();
  const double m2 = parallel_max(p.size(), 0.0, [&](std::size_t i) {
    const double dx = p.x[i] - x0_[i], dy = p.y[i] - y0_[i], dz = p.z[i] - z0_[i];
    return dx * dx + dy * dy + dz * dz;
  });
  return std::sqrt(m2);
}

bool NeighborList::needs_rebuild(const ParticleStore& p) const {
  if (builds_ == 0 || x0_.size() != p.size()) return true;
  return rebuild_due(max_displacement(p), 0.0, skin_);
}

std::vector<std::size_t> NeighborList::spatial_order(const ParticleStore& p, double skin) {
  const std::size_t N = p.size();
  std::vector<std::size_t> order(N);
  std::iota(order.begin(), order.end(), std::size_t{0});
  if (N == 0) return order;
  const Bounds B = particle_bounds(p);
  const double r_max = *std::max_element(p.radius.begin(), p.radius.end());
  const double h = column_side(r_max, skin);  // the column side used by build_columns()
  long n[3];
  for (int d = 0; d < 3; ++d) {
    n[d] = std::max(1L, static_cast<long>(std::ceil((B.hi[d] - B.lo[d]) / h)));
  }
  std::vector<long> key(N);
  const double* c[3] = {p.x.data(), p.y.data(), p.z.data()};
  for (std::size_t i = 0; i < N; ++i) {
    long cc[3];
    for (int d = 0; d < 3; ++d) {
      cc[d] = std::clamp(static_cast<long>(std::floor((c[d][i] - B.lo[d]) / h)), 0L, n[d] - 1);
    }
    key[i] = (cc[2] * n[1] + cc[1]) * n[0] + cc[0];
  }
  parallel_stable_sort(order, [&](std::size_t a, std::size_t b) { return key[a] < key[b]; });
  return order;
}

void NeighborList::state(StateArchive& a) {
  a.section("neighbors");
  a(offsets, neighbors, column_offsets, column_members, color_offsets, owner, skin_);
  builds_ = static_cast<std::size_t>(a.value(static_cast<std::uint64_t>(builds_)));
  a(x0_, y0_, z0_);
  if (!a.loading()) return;
  check_loaded();
  sum_column_work();  // derived, not stored
}

void NeighborList::check_loaded() const {
  // A loaded list indexes the particle arrays in the pair loop: every index and range is
  // checked here, so that a damaged state is refused instead of read out of bounds.
  const auto fail = [](const char* what) {
    throw RuntimeFailure(std::string("checkpoint: the neighbour list is damaged (") + what + ")");
  };
  const auto ranges = [&](const std::vector<Index>& off, std::size_t total, const char* what) {
    if (off.empty()) return;
    if (off.front() != 0 || off.back() != total) fail(what);
    for (std::size_t k = 1; k < off.size(); ++k) {
      if (off[k] < off[k - 1]) fail(what);
    }
  };
  if (offsets.empty()) return;  // no list yet: the next step builds one
  const std::size_t n = offsets.size() - 1;
  ranges(offsets, neighbors.size(), "offsets");
  for (const Index j : neighbors) {
    if (j >= n) fail("a neighbour index");
  }
  if (!owner.empty()) {
    if (owner.size() != neighbors.size()) fail("owners");
    for (const Index i : owner) {
      if (i >= n) fail("an owner index");
    }
  }
  ranges(column_offsets, column_members.size(), "columns");
  for (const Index i : column_members) {
    if (i >= n) fail("a column member");
  }
  const std::size_t columns = column_offsets.empty() ? 0 : column_offsets.size() - 1;
  if (!color_offsets.empty()) {
    if (color_offsets.size() != kColors + 1 || color_offsets.front() != 0 ||
        color_offsets.back() != columns) {
      fail("colours");
    }
    for (std::size_t k = 1; k < color_offsets.size(); ++k) {
      if (color_offsets[k] < color_offsets[k - 1]) fail("colours");
    }
  }
  if (x0_.size() != n || y0_.size() != n || z0_.size() != n) fail("reference positions");
}

}  // namespace crushdem
