#include "crushdem/integrate/contact_history.hpp"

#include <algorithm>
#include <cstddef>
#include <tuple>
#include <utility>

#include "crushdem/core/deterministic.hpp"

namespace crushdem {

namespace {

bool wall_key_less(const ContactHistory::WallVector& u, const ContactHistory::WallVector& v) {
  return std::tie(u.id, u.wall) < std::tie(v.id, v.wall);
}

}  // namespace

void ContactHistory::declare(const std::vector<HistoryField>& fields) {
  fields_ = fields;
  pair.assign(fields.size(), Vectors{});
  kept_pairs.assign(fields.size(), {});
  kept = false;
}

void ContactHistory::capture_pair_vectors(const ParticleStore& p, const NeighborList& nl,
                                          const Vectors& v, std::vector<PairVector>& out) const {
  out.clear();
  for (std::size_t e = 0; e < v.x.size(); ++e) {
    if (v.x[e] == 0.0 && v.y[e] == 0.0 && v.z[e] == 0.0) continue;
    const ParticleId ia = p.id[nl.owner[e]], ib = p.id[nl.neighbors[e]];
    if (ia < ib) {
      out.push_back({ia, ib, v.x[e], v.y[e], v.z[e]});
    } else {
      out.push_back({ib, ia, -v.x[e], -v.y[e], -v.z[e]});
    }
  }
  std::sort(out.begin(), out.end());
}

void ContactHistory::restore_pair_vectors(const ParticleStore& p, const NeighborList& nl,
                                          const std::vector<PairVector>& saved, Vectors& v) {
  if (saved.empty()) return;
  const std::size_t M = nl.neighbors.size();
#pragma omp parallel for schedule(static) if (worth_threading(M))
  for (std::ptrdiff_t ee = 0; ee < static_cast<std::ptrdiff_t>(M); ++ee) {
    const auto e = static_cast<std::size_t>(ee);
    const ParticleId ia = p.id[nl.owner[e]], ib = p.id[nl.neighbors[e]];
    const ParticleId a = std::min(ia, ib), b = std::max(ia, ib);
    auto it = std::lower_bound(saved.begin(), saved.end(), PairVector{a, b, 0, 0, 0});
    if (it != saved.end() && it->a == a && it->b == b) {
      const double s = ia == a ? 1.0 : -1.0;
      v.x[e] = s * it->x;
      v.y[e] = s * it->y;
      v.z[e] = s * it->z;
      touching[e] = 1;  // makes the force pass clear it if the pair has separated
    }
  }
}

void ContactHistory::capture(const ParticleStore& p, const NeighborList& nl,
                             const WallContacts& wc) {
  if (kept) return;
  for (std::size_t k = 0; k < pair.size(); ++k) {
    capture_pair_vectors(p, nl, pair[k], kept_pairs[k]);
  }
  kept_walls.clear();
  for (std::size_t e = 0; e < wc.size(); ++e) {
    if (wc.ft_x[e] == 0.0 && wc.ft_y[e] == 0.0 && wc.ft_z[e] == 0.0) continue;
    kept_walls.push_back({p.id[wc.particle[e]], wc.wall[e], wc.ft_x[e], wc.ft_y[e], wc.ft_z[e]});
  }
  std::sort(kept_walls.begin(), kept_walls.end(), wall_key_less);
  kept = true;
}

void ContactHistory::rebuild(const ParticleStore& p, const NeighborList& nl, WallContacts& wc) {
  const std::size_t M = nl.neighbors.size();
  for (Vectors& v : pair) {
    for (auto* a : {&v.x, &v.y, &v.z}) a->assign(M, 0.0);
  }
  touching.assign(M, 0);
  if (!kept) return;
  for (std::size_t k = 0; k < pair.size(); ++k) {
    restore_pair_vectors(p, nl, kept_pairs[k], pair[k]);
  }
  for (std::size_t e = 0; e < wc.size(); ++e) {
    const WallVector key{p.id[wc.particle[e]], wc.wall[e], 0, 0, 0};
    auto it = std::lower_bound(kept_walls.begin(), kept_walls.end(), key, wall_key_less);
    if (it != kept_walls.end() && it->id == key.id && it->wall == key.wall) {
      wc.ft_x[e] = it->x;
      wc.ft_y[e] = it->y;
      wc.ft_z[e] = it->z;
    }
  }
  for (auto& k : kept_pairs) k.clear();
  kept_walls.clear();
  kept = false;
}

ContactHistory::Previous ContactHistory::take(NeighborList& nl, WallContacts& wc) {
  Previous prev;
  prev.offsets = std::move(nl.offsets);
  prev.neighbors = std::move(nl.neighbors);
  prev.pair = std::move(pair);
  pair.assign(fields_.size(), Vectors{});
  prev.wall_offsets = std::move(wc.offsets);
  prev.wall = std::move(wc.wall);
  prev.ft_x = std::move(wc.ft_x);
  prev.ft_y = std::move(wc.ft_y);
  prev.ft_z = std::move(wc.ft_z);
  return prev;
}

void ContactHistory::carry(const Previous& prev, const std::vector<std::size_t>& from,
                           const NeighborList& nl, WallContacts& wc) {
  const std::size_t M = nl.neighbors.size();
  for (Vectors& v : pair) {
    for (auto* a : {&v.x, &v.y, &v.z}) a->assign(M, 0.0);
  }
  touching.assign(M, 0);
  const std::size_t n_old = prev.offsets.empty() ? 0 : prev.offsets.size() - 1;
  const auto old_index = [&](std::size_t k) { return from.empty() ? k : from[k]; };
  constexpr std::size_t kNone = ~std::size_t{0};
  // The old entry of the pair (a, b) owned by a, from a's row (sorted by partner).
  const auto entry = [&](std::size_t a, std::size_t b) {
    if (a >= n_old) return kNone;
    const auto first = prev.neighbors.begin() + prev.offsets[a];
    const auto last = prev.neighbors.begin() + prev.offsets[a + 1];
    const auto it = std::lower_bound(first, last, static_cast<NeighborList::Index>(b));
    return it != last && *it == b ? static_cast<std::size_t>(it - prev.neighbors.begin()) : kNone;
  };
#pragma omp parallel for schedule(static) if (worth_threading(M))
  for (std::ptrdiff_t ee = 0; ee < static_cast<std::ptrdiff_t>(M); ++ee) {
    const auto e = static_cast<std::size_t>(ee);
    const std::size_t i = old_index(nl.owner[e]), j = old_index(nl.neighbors[e]);
    // A half list holds a pair once, owned by either grain; owned by the other before, the
    // vector (on the owner) changes sign.
    double s = 1.0;
    std::size_t o = entry(i, j);
    if (o == kNone) {
      o = entry(j, i);
      s = -1.0;
    }
    if (o == kNone) continue;
    for (std::size_t k = 0; k < pair.size(); ++k) {
      const Vectors& u = prev.pair[k];
      // Zero vectors are not carried (capture() keeps none): the entry keeps +0.
      if (u.x[o] == 0.0 && u.y[o] == 0.0 && u.z[o] == 0.0) continue;
      pair[k].x[e] = s * u.x[o];
      pair[k].y[e] = s * u.y[o];
      pair[k].z[e] = s * u.z[o];
      touching[e] = 1;
    }
  }
  const std::size_t Mw = wc.size();
  const std::size_t nw_old = prev.wall_offsets.empty() ? 0 : prev.wall_offsets.size() - 1;
#pragma omp parallel for schedule(static) if (worth_threading(Mw))
  for (std::ptrdiff_t ee = 0; ee < static_cast<std::ptrdiff_t>(Mw); ++ee) {
    const auto e = static_cast<std::size_t>(ee);
    const std::size_t i = old_index(wc.particle[e]);
    if (i >= nw_old) continue;
    for (std::uint32_t o = prev.wall_offsets[i]; o < prev.wall_offsets[i + 1]; ++o) {
      if (prev.wall[o] != wc.wall[e]) continue;
      if (prev.ft_x[o] != 0.0 || prev.ft_y[o] != 0.0 || prev.ft_z[o] != 0.0) {
        wc.ft_x[e] = prev.ft_x[o];
        wc.ft_y[e] = prev.ft_y[o];
        wc.ft_z[e] = prev.ft_z[o];
      }
      break;
    }
  }
}

std::size_t ContactHistory::memory_bytes() const {
  std::size_t b = 0;
  for (const Vectors& v : pair) {
    for (const auto* a : {&v.x, &v.y, &v.z}) b += a->capacity() * sizeof(double);
  }
  return b + touching.capacity();
}

}  // namespace crushdem
