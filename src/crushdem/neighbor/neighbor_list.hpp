// Verlet neighbour list built from a multi-level cell grid.
//
// Particles are sorted into levels by radius (level L holds radii in (r_max/2^(L+1), r_max/2^L]),
// each level with its own cell grid of side 2 r_max/2^L + skin. A particle queries only the
// levels of particles at least as large as itself, where a query box a few cells wide suffices,
// so the cost per particle stays bounded with a 1:30 (or larger) radius ratio: a fragment never
// scans the thousands of small cells a large grain would cover, and a large grain never scans
// a fine grid.
//
// The list is a half list in CSR form: each pair (i, j) is stored once, owned by the smaller
// particle (higher level), or by the lower index within a level. The list is rebuilt when any
// particle has moved more than half the skin since the last build.
//
// Race-free, deterministic scatter: particles are grouped into columns, the (y, z) cells of side
// 2 r_max + skin. No pair can span more than one column in y or z, so an owner writes only into
// its own column and the 8 around it. Columns are coloured (y mod 3, z mod 3): columns of one
// colour never share a particle they write to, so each colour is processed in parallel and the
// nine colours one after another. Each particle's force is then summed in an order fixed by the
// columns, not by the threads, and the results are bit-identical for any thread count.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "crushdem/core/state_io.hpp"
#include "crushdem/particles/particle_store.hpp"

namespace crushdem {

/// The rebuild rule, used by every backend: a pair can appear only after its two grains have
/// together moved more than the skin (2 max|dx| > skin), a wall contact only after grain and wall
/// together have (max|dx| + wall travel > skin).
CD_HD inline bool rebuild_due(double max_displacement, double wall_travel, double skin) {
  return 2.0 * max_displacement > skin || max_displacement + wall_travel > skin;
}

class NeighborList {
 public:
  using Index = std::uint32_t;

  /// Builds the list for a cutoff of r_i + r_j + skin.
  void build(const ParticleStore& p, double skin);

  /// Largest displacement of any particle since the last build.
  double max_displacement(const ParticleStore& p) const;
  /// True when the list may miss a pair (2 max displacement > skin) or the particle count changed.
  bool needs_rebuild(const ParticleStore& p) const;

  /// A permutation of particle indices in cell order (cells of side 2 r_max + skin, z then y
  /// then x), so that each column of the coloured scatter is one contiguous range: better
  /// cache locality, and threads never write to the same cache line.
  static std::vector<std::size_t> spatial_order(const ParticleStore& p, double skin);

  std::size_t num_particles() const { return offsets.empty() ? 0 : offsets.size() - 1; }
  std::size_t num_pairs() const { return neighbors.size(); }
  double skin() const { return skin_; }
  std::size_t builds() const { return builds_; }
  /// Positions at the last build (the reference of the displacement criterion).
  const std::vector<double>& x_ref() const { return x0_; }
  const std::vector<double>& y_ref() const { return y0_; }
  const std::vector<double>& z_ref() const { return z0_; }

  /// The list, its columns and the reference positions, bit for bit (checkpoints: a list
  /// rebuilt at another step would order the force sums differently).
  void state(StateArchive& a);

  // CSR half list: the partners of i are neighbors[offsets[i] .. offsets[i+1]).
  std::vector<Index> offsets, neighbors;
  // Columns: the particles of column c are column_members[column_offsets[c] ..
  // column_offsets[c+1]) in increasing index; the columns of colour k (0..8) are
  // color_offsets[k] .. color_offsets[k+1].
  static constexpr int kColors = 9;
  std::vector<Index> column_offsets, column_members;
  std::vector<Index> color_offsets;
  // Pair-loop work before each column (prefix sums of 1 + entries over its particles; one more
  // element than columns), so each thread can take a contiguous, balanced share of a colour.
  std::vector<std::uint64_t> column_work;
  // Owner of each entry (i for entry e in i's range), kept to make entry loops flat.
  std::vector<Index> owner;

 private:
  void build_columns(const ParticleStore& p, const double lo[3], double h);
  void sum_column_work();
  void check_loaded() const;  // RuntimeFailure when a loaded list indexes out of bounds
  double skin_ = 0.0;
  std::size_t builds_ = 0;
  std::vector<double> x0_, y0_, z0_;  // positions at the last build
};

}  // namespace crushdem
