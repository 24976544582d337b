// Contact history: what a contact carries from one step to the next (the tangential spring
// force, the rolling moment with rolling resistance on, whether it touched), per entry of the
// neighbour list and of the wall contacts, kept across neighbour rebuilds and topology changes
// by particle ids.
//
// Entries are indices into lists that change: a rebuild re-sorts the particles and makes a new
// list, a topology change compacts the store. Before indices change, capture() keeps every
// nonzero vector keyed by (smaller id, larger id) as the vector on the smaller id (or by
// (particle id, wall)); after the new lists are made, rebuild() sizes the per-entry arrays and
// puts each kept vector back by binary search, marking the entry touching so that the next force
// pass clears it if the pair has separated.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "crushdem/core/state_io.hpp"
#include "crushdem/neighbor/neighbor_list.hpp"
#include "crushdem/particles/particle_store.hpp"
#include "crushdem/walls/walls.hpp"

namespace crushdem {

class ContactHistory {
 public:
  /// A vector kept by ids: the pair (a < b) and its value on a.
  struct PairVector {
    ParticleId a, b;
    double x, y, z;
    bool operator<(const PairVector& o) const { return a < o.a || (a == o.a && b < o.b); }
  };
  /// A wall entry's tangential force kept by (particle id, wall).
  struct WallVector {
    ParticleId id;
    int wall;
    double x, y, z;
  };

  // Per neighbour entry: the tangential force on the owner, the rolling moment on the owner
  // (rolling resistance only; empty otherwise) and whether the pair touched at the last pass.
  std::vector<double> ft_x, ft_y, ft_z;
  std::vector<double> mr_x, mr_y, mr_z;
  std::vector<std::uint8_t> touching;

  /// Keeps the history of the current lists by ids (nothing when kept already and not yet put
  /// back): called before any change of particle indices.
  void capture(const ParticleStore& p, const NeighborList& nl, const WallContacts& wc);
  /// After a new list: the per-entry arrays sized to it (zero; the rolling ones only with
  /// `rolling`), then what capture() kept put back on the matching entries (walls into wc).
  void rebuild(const ParticleStore& p, const NeighborList& nl, WallContacts& wc, bool rolling);
  std::size_t memory_bytes() const;

  // What capture() kept (saved in checkpoints: a state may be saved between capture() and
  // rebuild()); `kept` until rebuild() has put it back.
  std::vector<PairVector> kept_pairs, kept_rolling;
  std::vector<WallVector> kept_walls;
  bool kept = false;

 private:
  void capture_pair_vectors(const ParticleStore& p, const NeighborList& nl,
                            const std::vector<double>& x, const std::vector<double>& y,
                            const std::vector<double>& z, std::vector<PairVector>& out) const;
  void restore_pair_vectors(const ParticleStore& p, const NeighborList& nl,
                            const std::vector<PairVector>& saved, std::vector<double>& x,
                            std::vector<double>& y, std::vector<double>& z);
};

}  // namespace crushdem
