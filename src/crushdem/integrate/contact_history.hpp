// Contact history: what a contact carries from one step to the next (each vector the contact law
// declares: the tangential spring force, the rolling moment with rolling resistance on; and
// whether it touched), per entry of the neighbour list and of the wall contacts, kept across
// neighbour rebuilds and topology changes by particle ids.
//
// Entries are indices into lists that change: a rebuild re-sorts the particles and makes a new
// list, a topology change compacts the store. Before a topology change, capture() keeps every
// nonzero vector keyed by (smaller id, larger id) as the vector on the smaller id (or by
// (particle id, wall)); after the new lists are made, rebuild() sizes the per-entry arrays and
// puts each kept vector back by binary search, marking the entry touching so that the next force
// pass clears it if the pair has separated. A rebuild of the same grains (the common case: every
// few dozen steps) needs no ids: take() moves the old lists and history out, and carry() looks
// each new pair up in its grains' old rows (sorted, a few entries long) through the rebuild's
// permutation. The two give the same bits; carry() sorts nothing and runs in parallel.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "crushdem/contact/history_field.hpp"
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
  /// One declared field's components per neighbour entry.
  struct Vectors {
    std::vector<double> x, y, z;
  };

  /// The history vectors each neighbour entry keeps, as the contact law declares them
  /// (ContactLaw::pair_history(): the tangential spring first); sizes `pair` and `kept_pairs`.
  void declare(const std::vector<HistoryField>& fields);
  const std::vector<HistoryField>& fields() const { return fields_; }

  // Per neighbour entry: each declared vector on the owner (pair[0]: the tangential spring
  // force), and whether the pair touched at the last pass.
  std::vector<Vectors> pair;
  std::vector<std::uint8_t> touching;
  Vectors& tangential() { return pair[0]; }
  const Vectors& tangential() const { return pair[0]; }

  /// Keeps the history of the current lists by ids (nothing when kept already and not yet put
  /// back): called before any change of particle indices.
  void capture(const ParticleStore& p, const NeighborList& nl, const WallContacts& wc);
  /// After a new list: the per-entry arrays sized to it (zero), then what capture() kept put
  /// back on the matching entries (walls into wc).
  void rebuild(const ParticleStore& p, const NeighborList& nl, WallContacts& wc);
  std::size_t memory_bytes() const;

  /// The lists and history of the last build, moved out before the lists are rebuilt for the
  /// same grains (their rows sorted by partner, as NeighborList::build leaves them).
  struct Previous {
    std::vector<NeighborList::Index> offsets, neighbors;
    std::vector<Vectors> pair;
    std::vector<std::uint32_t> wall_offsets;
    std::vector<std::uint8_t> wall;
    std::vector<double> ft_x, ft_y, ft_z;
  };
  /// Moves the current lists' entries and history out (the lists are rebuilt next).
  Previous take(NeighborList& nl, WallContacts& wc);
  /// After new lists of the same grains, where new grain k was grain from[k] of `prev` (from
  /// empty: grain k): the per-entry arrays sized to the new lists, and every nonzero vector on
  /// the entry of the same pair (or grain and body), touching as rebuild() marks it. The same
  /// bits as capture() before the change and rebuild() after.
  void carry(const Previous& prev, const std::vector<std::size_t>& from, const NeighborList& nl,
             WallContacts& wc);

  // What capture() kept, per declared field (saved in checkpoints: a state may be saved between
  // capture() and rebuild()); `kept` until rebuild() has put it back.
  std::vector<std::vector<PairVector>> kept_pairs;
  std::vector<WallVector> kept_walls;
  bool kept = false;

 private:
  void capture_pair_vectors(const ParticleStore& p, const NeighborList& nl, const Vectors& v,
                            std::vector<PairVector>& out) const;
  void restore_pair_vectors(const ParticleStore& p, const NeighborList& nl,
                            const std::vector<PairVector>& saved, Vectors& v);
  std::vector<HistoryField> fields_;
};

}  // namespace crushdem
