#include "crushdem/integrate/pair_loop.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <type_traits>

#include "crushdem/contact/contact_kernel.hpp"
#include "crushdem/core/deterministic.hpp"

namespace crushdem {

namespace {

using Idx = std::ptrdiff_t;

// Everything the pair loop touches, passed by value into the per-column worker so the compiler
// sees plain locals (inside an OpenMP region shared variables are reached through a pointer and
// reloaded after every store, which cost 10 % of the step).
template <class Model>
struct PairLoopView {
  typename Model::Law law;
  ContactParams cp;
  typename Model::CoupleModel::Params couple;
  double h;
  const NeighborList::Index *off, *nb, *col_off, *col_mem;
  const double *X, *Y, *Z, *R, *VX, *VY, *VZ, *WX, *WY, *WZ;
  double *ftx, *fty, *ftz;
  std::uint8_t* touch;
  // The couple sub-model's history vector (the rolling moment; Model::kCouple only).
  double *chx = nullptr, *chy = nullptr, *chz = nullptr;
  // Contact load (crushing), null when not tracked: max sigma_c, max F_n and its normal.
  double *LS = nullptr, *LF = nullptr, *LNX = nullptr, *LNY = nullptr, *LNZ = nullptr;
  double inv_pi_k = 0.0;                // 1 / (pi r'/R*)
  detail::PackedPosition* P = nullptr;  // filled at the start of the loop from X .. R
  detail::PackedVelocity* V = nullptr;  // from VX .. WZ
  detail::PackedForce* PF = nullptr;    // the sums, zeroed at the start of the loop
  const double* IM = nullptr;           // inverse masses (into V)
  // The pruned list (PruneMode::Build writes it, Use reads it) and its inner skin.
  PrunedList::Entry* near = nullptr;
  NeighborList::Index* near_count = nullptr;
  double inner_skin = 0.0;
};

// The CPU pair loop works on batches of touching contacts, in three passes per batch:
//   1. collect: walk the column's particles and their entries in order, test the overlap, and
//      copy each touching pair's inputs into a struct-of-arrays batch (clearing the history of
//      pairs that separated);
//   2. evaluate: one `omp simd` loop over the batch calls the same pair_contact() kernel as the
//      GPU, so the compiler vectorises it (8 contacts per AVX-512 instruction);
//   3. scatter: replay the batch in the collect order, adding each contact to both grains
//      exactly as the one-pass loop did.
// Vector lanes compute each contact with the same IEEE operations as a scalar evaluation (no
// contraction, no reassociation), and the sums are made in the same order as before, so the
// results are bit-identical to the one-pass loop and independent of the thread count.
// clang-format off
enum BatchField : std::size_t {
  // inputs
  kDX, kDY, kDZ, kD2, kRI, kRJ, kDVX, kDVY, kDVZ, kWIX, kWIY, kWIZ, kWJX, kWJY, kWJZ, kIMI, kIMJ,
  // inputs (the couple's history: overwritten by the new one)
  kFTX, kFTY, kFTZ, kCHX, kCHY, kCHZ,
  // outputs
  kFX, kFY, kFZ, kTNX, kTNY, kTNZ, kAI, kAJ, kFN, kDELTA, kNX, kNY, kNZ,
  // the new history
  kNFTX, kNFTY, kNFTZ,
  kBatchFields
};
// clang-format on

// Each column of a batch ends in kBatchPad spare slots, so that a group of four slots starting at
// any used slot stays inside its column (scatter_sums() reads whole groups and ignores the lanes
// past the fill).
inline constexpr std::size_t kBatchPad = 4;

// The kBatchFields columns of a batch, column k at data + k (cap + kBatchPad). kCap: the cap as
// a compile-time constant, for the fixed-size batch that holds nearly every contact: each column
// is then one register plus a constant offset. With the cap a run-time value (kCap = 0, the
// batch of a grain with more list entries than the fixed one holds) the loops over a batch need
// the 40 column addresses in registers, x86-64 has 16, and every load or store first reloaded
// its address from the stack (a fifth of the collect pass's instructions).
template <std::size_t kCap>
struct BatchView {
  double* data;
  std::size_t cap;  // read only when kCap == 0
  double* f(BatchField k) const { return data + k * ((kCap != 0 ? kCap : cap) + kBatchPad); }
};

}  // namespace

// One thread's batch: kBatchFields arrays of `cap` (+ kBatchPad) doubles, plus the entry, partner
// and owner bookkeeping of the scatter pass, and a second set of arrays for the contacts that need
// the exact evaluation (evaluate_batch()). Aligned to a cache line: each thread's batches are its
// own heap blocks, and their counters, written at every flush, share no line with another's.
struct alignas(64) detail::PairBatch {
  // Slots of the fixed-size batch (about 43 KB, fits in L2): the list entries of the grains in
  // it, of which the touching ones are kept. That batch is reserved once with exactly this
  // capacity and never grown, so its views may use the constant (view<kTarget>()).
  static constexpr std::size_t kTarget = 136;
  std::size_t cap = 0;
  std::vector<double> data, exact_data;
  std::vector<NeighborList::Index> entry, partner;
  // Particles of the batch with a touching contact (at most cap), the end of each one's contacts.
  std::vector<NeighborList::Index> owner, owner_end;
  std::size_t owners = 0;
  std::vector<std::size_t> exact_lane;  // batch slot of each exact contact
  std::size_t exact_only = 0;  // batches still to evaluate exactly at once (evaluate_batch())
  void reserve(std::size_t n) {
    if (n <= cap) return;
    cap = std::max(n, kTarget);
    data.assign((cap + kBatchPad) * kBatchFields, 0.0);
    exact_data.assign((cap + kBatchPad) * kBatchFields, 0.0);
    entry.resize(cap);
    partner.resize(cap);
    owner.resize(cap);
    owner_end.resize(cap);
    exact_lane.resize(cap);
  }
  template <std::size_t kCap>
  BatchView<kCap> view() {
    return {data.data(), cap};
  }
  template <std::size_t kCap>
  BatchView<kCap> exact_view() {
    return {exact_data.data(), cap};
  }
  std::size_t memory_bytes() const {
    return (data.capacity() + exact_data.capacity()) * sizeof(double) +
           (entry.capacity() + partner.capacity() + owner.capacity() + owner_end.capacity()) *
               sizeof(NeighborList::Index) +
           exact_lane.capacity() * sizeof(std::size_t);
  }
};

namespace {
using detail::PairBatch;

// Evaluates contacts 0 .. n-1 of a batch in vector lanes; kFastPath: without the rare steps
// (contact_plane_spring()).
// Not inlined: inlined into evaluate_batch() with a fixed-size batch, GCC sees every column as
// one base plus a constant offset, stops trusting the restrict pointers, and (for the rough
// law) left the loop scalar.
// `law` is the pair loop's law or a variant of it for this batch (evaluate_batch()); by value,
// with cp and h, so that the loop reads them from registers.
template <class Couple, bool kCouple, bool kFastPath, class LaneLaw, class View>
[[gnu::noinline]] void evaluate_lanes(const LaneLaw law, const ContactParams cp,
                                      const typename Couple::Params couple, const double h, View b,
                                      std::size_t n) {
  // Named restrict pointers (not an array of them): the compiler must see that the stores
  // into the batch cannot change where its columns are, or it does not vectorise.
  double* __restrict const bDX = b.f(kDX);
  double* __restrict const bDY = b.f(kDY);
  double* __restrict const bDZ = b.f(kDZ);
  double* __restrict const bD2 = b.f(kD2);
  double* __restrict const bRI = b.f(kRI);
  double* __restrict const bRJ = b.f(kRJ);
  double* __restrict const bDVX = b.f(kDVX);
  double* __restrict const bDVY = b.f(kDVY);
  double* __restrict const bDVZ = b.f(kDVZ);
  double* __restrict const bWIX = b.f(kWIX);
  double* __restrict const bWIY = b.f(kWIY);
  double* __restrict const bWIZ = b.f(kWIZ);
  double* __restrict const bWJX = b.f(kWJX);
  double* __restrict const bWJY = b.f(kWJY);
  double* __restrict const bWJZ = b.f(kWJZ);
  double* __restrict const bIMI = b.f(kIMI);
  double* __restrict const bIMJ = b.f(kIMJ);
  double* __restrict const bFTX = b.f(kFTX);
  double* __restrict const bFTY = b.f(kFTY);
  double* __restrict const bFTZ = b.f(kFTZ);
  double* __restrict const bCHX = b.f(kCHX);
  double* __restrict const bCHY = b.f(kCHY);
  double* __restrict const bCHZ = b.f(kCHZ);
  double* __restrict const bFX = b.f(kFX);
  double* __restrict const bFY = b.f(kFY);
  double* __restrict const bFZ = b.f(kFZ);
  double* __restrict const bTNX = b.f(kTNX);
  double* __restrict const bTNY = b.f(kTNY);
  double* __restrict const bTNZ = b.f(kTNZ);
  double* __restrict const bAI = b.f(kAI);
  double* __restrict const bAJ = b.f(kAJ);
  double* __restrict const bFN = b.f(kFN);
  double* __restrict const bDELTA = b.f(kDELTA);
  double* __restrict const bNX = b.f(kNX);
  double* __restrict const bNY = b.f(kNY);
  double* __restrict const bNZ = b.f(kNZ);
  double* __restrict const bNFTX = b.f(kNFTX);
  double* __restrict const bNFTY = b.f(kNFTY);
  double* __restrict const bNFTZ = b.f(kNFTZ);
#pragma omp simd
  for (std::size_t m = 0; m < n; ++m) {
    // R*, its root and the effective mass: cheaper here, in vector lanes, than cached per entry
    // and read (the GPU upload computes the same expressions).
    const double R_star = pair_R_star(bRI[m], bRJ[m]);
    const double m_eff = pair_m_eff(bIMI[m], bIMJ[m]);
    const PairContact pc = pair_contact<LaneLaw, kFastPath>(
        law, Vec3{bDX[m], bDY[m], bDZ[m]}, bD2[m], bRI[m], bRJ[m], Vec3{bDVX[m], bDVY[m], bDVZ[m]},
        Vec3{bWIX[m], bWIY[m], bWIZ[m]}, Vec3{bWJX[m], bWJY[m], bWJZ[m]}, R_star, std::sqrt(R_star),
        m_eff, Vec3{bFTX[m], bFTY[m], bFTZ[m]}, cp, h);
    bFX[m] = pc.c.force.x;
    bFY[m] = pc.c.force.y;
    bFZ[m] = pc.c.force.z;
    bNFTX[m] = pc.c.F_t.x;
    bNFTY[m] = pc.c.F_t.y;
    bNFTZ[m] = pc.c.F_t.z;
    bTNX[m] = pc.tn.x;
    bTNY[m] = pc.tn.y;
    bTNZ[m] = pc.tn.z;
    bAI[m] = pc.a_i;
    bAJ[m] = pc.a_j;
    bFN[m] = pc.c.F_n;
    bDELTA[m] = pc.delta;
    bNX[m] = pc.n.x;
    bNY[m] = pc.n.y;
    bNZ[m] = pc.n.z;
    if constexpr (kCouple) {
      const Vec3 M_r =
          Couple::moment(couple, pc.n, pc.c.k_n, pc.c.F_n, Vec3{bCHX[m], bCHY[m], bCHZ[m]},
                         Vec3{bWIX[m], bWIY[m], bWIZ[m]}, Vec3{bWJX[m], bWJY[m], bWJZ[m]}, R_star,
                         cp.tangential_ratio, h);
      bCHX[m] = M_r.x;
      bCHY[m] = M_r.y;
      bCHZ[m] = M_r.z;
    }
  }
}

// Evaluates a batch: every contact on the fast path, in vector lanes; then the few that need
// the exact path (a sliding contact, a turned contact plane) copied into the second arrays,
// evaluated exactly (also in vector lanes) and copied back. Each contact gets the bits of an
// exact evaluation either way, so the results do not depend on how contacts fall into batches.
// (The rolling moment is exact in the first pass and not evaluated again.)
template <class Model, std::size_t kCap, class LaneLaw>
void evaluate_batch_with(const LaneLaw& law, const PairLoopView<Model>& L, PairBatch& b,
                         std::size_t n) {
  using Couple = typename Model::CoupleModel;
  const BatchView<kCap> main = b.view<kCap>();
  // Where most contacts slide (shearing, a sample out of equilibrium) the fast path only adds a
  // second evaluation: after a batch with more than a quarter of its contacts on the exact path,
  // the next kExactOnly batches go straight to it. Both paths give the same bits, so which one
  // runs changes no result (and may differ between threads).
  constexpr std::size_t kExactOnly = 64;
  if (b.exact_only > 0) {
    --b.exact_only;
    evaluate_lanes<Couple, Model::kCouple, false>(law, L.cp, L.couple, L.h, main, n);
    return;
  }
  evaluate_lanes<Couple, Model::kCouple, true>(law, L.cp, L.couple, L.h, main, n);
  // The contacts where a rare step applies (branch-free, as in the collect pass).
  const double* nftx = main.f(kNFTX);
  std::size_t* const lane = b.exact_lane.data();
  std::size_t ne = 0;
  for (std::size_t m = 0; m < n; ++m) {
    lane[ne] = m;
    ne += fast_path_inexact(nftx[m]) ? 1 : 0;
  }
  if (ne == 0) return;
  if (4 * ne > n) b.exact_only = kExactOnly;
  constexpr BatchField kInputs[] = {kDX,  kDY,  kDZ,  kD2,  kRI,  kRJ,  kDVX, kDVY, kDVZ, kWIX,
                                    kWIY, kWIZ, kWJX, kWJY, kWJZ, kIMI, kIMJ, kFTX, kFTY, kFTZ};
  constexpr BatchField kOutputs[] = {kFX,  kFY, kFZ, kNFTX, kNFTY,  kNFTZ, kTNX, kTNY,
                                     kTNZ, kAI, kAJ, kFN,   kDELTA, kNX,   kNY,  kNZ};
  const BatchView<kCap> side = b.exact_view<kCap>();
  for (const BatchField f : kInputs) {
    const double* from = main.f(f);
    double* to = side.f(f);
    for (std::size_t k = 0; k < ne; ++k) to[k] = from[lane[k]];
  }
  evaluate_lanes<Couple, false, false>(law, L.cp, L.couple, L.h, side, ne);
  for (const BatchField f : kOutputs) {
    const double* from = side.f(f);
    double* to = main.f(f);
    for (std::size_t k = 0; k < ne; ++k) to[lane[k]] = from[k];
  }
}

// A normal law that has a cheaper variant for contacts that cannot reach one of its regimes
// (the rough law without its Hertz regime): may_need_full() tells per contact.
template <class Law>
concept HasLaneVariant = requires(const Law& law) {
  law.without_hertz_regime();
  law.may_need_full(0.0, 0.0);
};

// Whether any of contacts 0 .. n-1 of a batch may need the law's full form, from the collected
// distances and radii: a vector reduction without square roots. (The same test in the collect
// pass, on scalars, cost more instructions than the regime saves: callgrind.)
template <std::size_t kCap, class Law>
bool batch_may_need_full(const Law& law, const BatchView<kCap> b, std::size_t n) {
  const double* __restrict const d2 = b.f(kD2);
  const double* __restrict const r_i = b.f(kRI);
  const double* __restrict const r_j = b.f(kRJ);
  int any = 0;
#pragma omp simd reduction(| : any)
  for (std::size_t m = 0; m < n; ++m) any |= law.may_need_full(d2[m], r_i[m] + r_j[m]) ? 1 : 0;
  return any != 0;
}

// Evaluates a batch with the pair loop's law, or, where the law has a cheaper variant and none
// of the batch's contacts needs the full form (the rough law in a sample at rest under a few
// MPa: no contact is in its Hertz regime), with the variant: the same bits for every contact,
// without a square root per lane.
template <class Model, std::size_t kCap>
void evaluate_batch(const PairLoopView<Model>& L, PairBatch& b, std::size_t n) {
  if constexpr (HasLaneVariant<typename Model::Law>) {
    if (!batch_may_need_full(L.law, b.view<kCap>(), n)) {
      evaluate_batch_with<Model, kCap>(L.law.without_hertz_regime(), L, b, n);
      return;
    }
  }
  evaluate_batch_with<Model, kCap>(L.law, L, b, n);
}

// The contact load of one contact (crushing): the largest contact stress on each grain, and the
// largest normal force with its normal. j is safe to write for the same reason as its sums
// (column colouring).
template <class Model, std::size_t kCap>
inline void record_contact_load(const PairLoopView<Model>& L, const BatchView<kCap> b,
                                std::size_t m, std::size_t i, std::size_t j) {
  const double F_n = b.f(kFN)[m];
  const Vec3 normal{b.f(kNX)[m], b.f(kNY)[m], b.f(kNZ)[m]};
  const double sig =
      pair_contact_stress(F_n, L.inv_pi_k, pair_R_star(b.f(kRI)[m], b.f(kRJ)[m]), b.f(kDELTA)[m]);
  take_contact_load(L.LS[i], L.LF[i], L.LNX[i], L.LNY[i], L.LNZ[i], sig, F_n, normal);
  take_contact_load(L.LS[j], L.LF[j], L.LNX[j], L.LNY[j], L.LNZ[j], sig, F_n, -normal);
}

// Four doubles in one vector register (AVX), or two SSE registers where there is no AVX: GCC
// lowers the same code either way.
using v4d = double __attribute__((vector_size(32)));
using v2d = double __attribute__((vector_size(16)));
inline v4d load4(const double* p) {
  v4d v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline v2d load2(const double* p) {
  v2d v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline void store4(double* p, v4d v) {
  std::memcpy(p, &v, sizeof v);
}
inline void store2(double* p, v2d v) {
  std::memcpy(p, &v, sizeof v);
}
// Lanes i, j, k, l of the eight of (a, b) (0-3 are a's, 4-7 b's), and lanes i, j of a. GCC
// before 12 has no __builtin_shufflevector: its __builtin_shuffle takes the same indices as a
// mask (the portable wheel of scripts/wheel_debian11.sh is built with GCC 10).
template <int i, int j, int k, int l>
inline v4d shuffle4(v4d a, v4d b) {
#if defined(__clang__) || __GNUC__ >= 12
  return __builtin_shufflevector(a, b, i, j, k, l);
#else
  using v4l = long long __attribute__((vector_size(32)));
  return __builtin_shuffle(a, b, v4l{i, j, k, l});
#endif
}
template <int i, int j>
inline v2d lanes2(v4d a) {
#if defined(__clang__) || __GNUC__ >= 12
  return __builtin_shufflevector(a, a, i, j);
#else
  return v2d{a[i], a[j]};
#endif
}
// Rows k = 0..3 of the 4 x 4 matrix whose columns are a, b, c, d: (a[k], b[k], c[k], d[k]).
inline void transpose4(v4d a, v4d b, v4d c, v4d d, v4d row[4]) {
  const v4d ab_even = shuffle4<0, 4, 2, 6>(a, b);  // a0 b0 a2 b2
  const v4d ab_odd = shuffle4<1, 5, 3, 7>(a, b);   // a1 b1 a3 b3
  const v4d cd_even = shuffle4<0, 4, 2, 6>(c, d);
  const v4d cd_odd = shuffle4<1, 5, 3, 7>(c, d);
  row[0] = shuffle4<0, 1, 4, 5>(ab_even, cd_even);
  row[1] = shuffle4<0, 1, 4, 5>(ab_odd, cd_odd);
  row[2] = shuffle4<2, 3, 6, 7>(ab_even, cd_even);
  row[3] = shuffle4<2, 3, 6, 7>(ab_odd, cd_odd);
}

// The scatter pass without a couple sub-model: each contact's force and torques added to both
// grains' sums (PackedForce: fx fy fz tx | ty tz) and its new history stored, in the collect
// order. Each grain's sums get the same IEEE operations in the same order as a scalar loop
// (x - (-y) is x + y exactly), so the bits do not change; but four contacts at a time are turned
// from the batch's columns into rows, so that a partner's six sums take one 4-wide and one
// 2-wide subtraction instead of six scalar ones.
template <class Model, std::size_t kCap>
void scatter_sums(const PairLoopView<Model>& L, PairBatch& pb, std::size_t n) {
  const BatchView<kCap> b = pb.view<kCap>();
  const double *fx = b.f(kFX), *fy = b.f(kFY), *fz = b.f(kFZ);
  const double *tnx = b.f(kTNX), *tny = b.f(kTNY), *tnz = b.f(kTNZ);
  const double *ai = b.f(kAI), *aj = b.f(kAJ);
  const double *ftx = b.f(kNFTX), *fty = b.f(kNFTY), *ftz = b.f(kNFTZ);
  const NeighborList::Index* const entry = pb.entry.data();
  const NeighborList::Index* const partner = pb.partner.data();
  const NeighborList::Index* const owner = pb.owner.data();
  const NeighborList::Index* const owner_end = pb.owner_end.data();
  double* const PF = &L.PF->fx;  // eight doubles per grain
  const v4d zero{0.0, 0.0, 0.0, 0.0};
  std::size_t q = 0;       // the owner of contact m
  v4d F = zero, T = zero;  // its sums so far: force (lanes 0-2), torque (lanes 0-2)
  const auto finish_owner = [&] {
    double* const sum = PF + 8 * std::size_t{owner[q]};
    store4(sum, load4(sum) + shuffle4<0, 1, 2, 4>(F, T));  // fx fy fz tx
    store2(sum + 4, load2(sum + 4) + lanes2<1, 2>(T));     // ty tz
    F = T = zero;
    ++q;
  };
  for (std::size_t m0 = 0; m0 < n; m0 += 4) {
    // Columns m0 .. m0+3 (kBatchPad; lanes past n are never used).
    const v4d AI = load4(ai + m0), AJ = load4(aj + m0);
    const v4d TX = load4(tnx + m0), TY = load4(tny + m0), TZ = load4(tnz + m0);
    v4d on_j[4], on_i_torque[4];
    // On j: fx fy fz subtracted, and aj tn_x added as the subtraction of its negative.
    transpose4(load4(fx + m0), load4(fy + m0), load4(fz + m0), -(AJ * TX), on_j);
    transpose4(AI * TX, AI * TY, AI * TZ, zero, on_i_torque);
    const v4d ajy = AJ * TY, ajz = AJ * TZ;
    const v4d yz_lo = shuffle4<0, 4, 1, 5>(ajy, ajz);  // y0 z0 y1 z1
    const v4d yz_hi = shuffle4<2, 6, 3, 7>(ajy, ajz);  // y2 z2 y3 z3
    const v2d on_j_yz[4] = {lanes2<0, 1>(yz_lo), lanes2<2, 3>(yz_lo), lanes2<0, 1>(yz_hi),
                            lanes2<2, 3>(yz_hi)};
    const std::size_t group = std::min<std::size_t>(4, n - m0);
    for (std::size_t k = 0; k < group; ++k) {
      const std::size_t m = m0 + k;
      if (m == owner_end[q]) finish_owner();
      const std::size_t e = entry[m];
      L.ftx[e] = ftx[m];
      L.fty[e] = fty[m];
      L.ftz[e] = ftz[m];
      F += on_j[k];  // lanes 0-2 (lane 3 is not used)
      T += on_i_torque[k];
      double* const sum = PF + 8 * std::size_t{partner[m]};
      store4(sum, load4(sum) - on_j[k]);
      store2(sum + 4, load2(sum + 4) + on_j_yz[k]);
    }
  }
  if (n > 0) finish_owner();
  if (L.LS) {  // the contact load, in the same order (a tie keeps the first normal)
    std::size_t m = 0;
    for (std::size_t r = 0; r < pb.owners; ++r) {
      for (; m < owner_end[r]; ++m) record_contact_load<Model, kCap>(L, b, m, owner[r], partner[m]);
    }
  }
}

// The scatter pass with a couple sub-model (rolling resistance; scalar): as scatter_sums(), plus
// the couple's moment on both grains and its new history.
template <class Model, std::size_t kCap>
void scatter_sums_couple(const PairLoopView<Model> L, PairBatch& pb) {
  const BatchView<kCap> b = pb.view<kCap>();
  const double *fx = b.f(kFX), *fy = b.f(kFY), *fz = b.f(kFZ);
  const double *tnx = b.f(kTNX), *tny = b.f(kTNY), *tnz = b.f(kTNZ);
  const double *ai = b.f(kAI), *aj = b.f(kAJ);
  const double *ftx = b.f(kNFTX), *fty = b.f(kNFTY), *ftz = b.f(kNFTZ);
  const double *chx = b.f(kCHX), *chy = b.f(kCHY), *chz = b.f(kCHZ);
  // Local copies of the bookkeeping pointers: they stay in registers through the stores below.
  const NeighborList::Index* const entry = pb.entry.data();
  const NeighborList::Index* const partner = pb.partner.data();
  const NeighborList::Index* const owner = pb.owner.data();
  const NeighborList::Index* const owner_end = pb.owner_end.data();
  const std::size_t owners = pb.owners;
  std::size_t m = 0;
  for (std::size_t q = 0; q < owners; ++q) {
    const std::size_t i = owner[q];
    Vec3 F{}, T{};
    for (; m < owner_end[q]; ++m) {
      const std::size_t e = entry[m], j = partner[m];
      L.ftx[e] = ftx[m];
      L.fty[e] = fty[m];
      L.ftz[e] = ftz[m];
      const Vec3 force{fx[m], fy[m], fz[m]};
      const Vec3 tn{tnx[m], tny[m], tnz[m]};
      F += force;
      T += ai[m] * tn;
      L.PF[j].fx -= force.x;
      L.PF[j].fy -= force.y;
      L.PF[j].fz -= force.z;
      L.PF[j].tx += aj[m] * tn.x;
      L.PF[j].ty += aj[m] * tn.y;
      L.PF[j].tz += aj[m] * tn.z;
      const Vec3 M_r{chx[m], chy[m], chz[m]};
      L.chx[e] = M_r.x;
      L.chy[e] = M_r.y;
      L.chz[e] = M_r.z;
      T += M_r;
      L.PF[j].tx -= M_r.x;
      L.PF[j].ty -= M_r.y;
      L.PF[j].tz -= M_r.z;
      if (L.LS) record_contact_load<Model, kCap>(L, b, m, i, j);
    }
    L.PF[i].fx += F.x;
    L.PF[i].fy += F.y;
    L.PF[i].fz += F.z;
    L.PF[i].tx += T.x;
    L.PF[i].ty += T.y;
    L.PF[i].tz += T.z;
  }
}

template <class Model, std::size_t kCap>
void flush_batch(const PairLoopView<Model> L, PairBatch& pb, std::size_t n) {
  evaluate_batch<Model, kCap>(L, pb, n);
  if constexpr (Model::kCouple) {
    scatter_sums_couple<Model, kCap>(L, pb);
  } else {
    scatter_sums<Model, kCap>(L, pb, n);
  }
  pb.owners = 0;
}

// A pair's batch inputs beyond the overlap test: radius of i, relative velocity, spins,
// inverse masses and the history of entry e, into slot m. (A transposed copy, four partners'
// velocity lines turned into columns with vector shuffles, measured 5 % slower on the whole
// step: bench/README.md, session 14.)
template <class Model, std::size_t kCap>
inline void write_motion_inputs(const PairLoopView<Model>& L, const BatchView<kCap> in,
                                std::size_t m, std::size_t e, double r_i,
                                const detail::PackedVelocity& vi,
                                const detail::PackedVelocity& vj) {
  in.f(kRI)[m] = r_i;
  in.f(kDVX)[m] = vi.vx - vj.vx;
  in.f(kDVY)[m] = vi.vy - vj.vy;
  in.f(kDVZ)[m] = vi.vz - vj.vz;
  in.f(kWIX)[m] = vi.wx;
  in.f(kWIY)[m] = vi.wy;
  in.f(kWIZ)[m] = vi.wz;
  in.f(kWJX)[m] = vj.wx;
  in.f(kWJY)[m] = vj.wy;
  in.f(kWJZ)[m] = vj.wz;
  in.f(kIMI)[m] = vi.inv_mass;
  in.f(kIMJ)[m] = vj.inv_mass;
  in.f(kFTX)[m] = L.ftx[e];
  in.f(kFTY)[m] = L.fty[e];
  in.f(kFTZ)[m] = L.ftz[e];
  if constexpr (Model::kCouple) {
    in.f(kCHX)[m] = L.chx[e];
    in.f(kCHY)[m] = L.chy[e];
    in.f(kCHZ)[m] = L.chz[e];
  }
}

// Appends the touching pairs of particle i to the batch from slot n on (the batch has room for
// all of i's entries); returns the new fill.
template <class Model, PruneMode kMode, std::size_t kCap>
std::size_t collect_particle(const PairLoopView<Model>& L, std::size_t i, PairBatch& b,
                             std::size_t n) {
  const BatchView<kCap> in = b.view<kCap>();
  const detail::PackedPosition pi = L.P[i];
  const detail::PackedVelocity vi = L.V[i];
  // Overlap test without a branch on its outcome: every entry is written to slot n and n
  // advances only for a touching pair. Whether a pair in the skin touches is a coin toss for
  // the branch predictor, and each mispredicted branch used to stall on the next partner's
  // position (a third of the pair loop's time).
  const std::size_t n_first = n;
  NeighborList::Index* const slot_entry = b.entry.data();  // in registers through the stores
  NeighborList::Index* const slot_partner = b.partner.data();
  const auto first = L.off[i];
  NeighborList::Index kept = 0;  // PruneMode::Build: entries written to the pruned list
  const auto visit = [&](NeighborList::Index e, NeighborList::Index j) {
    const detail::PackedPosition pj = L.P[j];
    const double dx = pj.x - pi.x, dy = pj.y - pi.y, dz = pj.z - pi.z;
    const double d2 = dx * dx + dy * dy + dz * dz;
    const double rsum = pi.r + pj.r;
    const bool touching = d2 < rsum * rsum;
    if (static_cast<int>(!touching) & static_cast<int>(L.touch[e])) {
      // The pair separated (rare): forget its history.
      L.ftx[e] = L.fty[e] = L.ftz[e] = 0.0;
      if constexpr (Model::kCouple) L.chx[e] = L.chy[e] = L.chz[e] = 0.0;
    }
    L.touch[e] = static_cast<std::uint8_t>(touching);
    slot_entry[n] = e;
    slot_partner[n] = j;
    in.f(kDX)[n] = dx;
    in.f(kDY)[n] = dy;
    in.f(kDZ)[n] = dz;
    in.f(kD2)[n] = d2;
    in.f(kRJ)[n] = pj.r;
    if constexpr (kMode == PruneMode::Use) {
      // Nearly every pruned entry touches: its other inputs are written here, in the same pass,
      // rather than in a second pass over the kept slots.
      write_motion_inputs<Model, kCap>(L, in, n, e, pi.r, vi, L.V[j]);
    }
    n += touching ? 1 : 0;
    if constexpr (kMode == PruneMode::Build) {
      // Kept when the gap is below the inner skin (every touching pair is); written to the next
      // slot either way, without a branch, like the batch.
      const double reach = rsum + L.inner_skin;
      L.near[first + kept] = {e, j};
      kept += d2 < reach * reach ? 1 : 0;
    }
  };
  if constexpr (kMode == PruneMode::Use) {
    const PrunedList::Entry* const near = L.near + first;
    const NeighborList::Index count = L.near_count[i];
    for (NeighborList::Index k = 0; k < count; ++k) visit(near[k].e, near[k].j);
  } else {
    for (auto e = first; e < L.off[i + 1]; ++e) visit(e, L.nb[e]);
    if constexpr (kMode == PruneMode::Build) L.near_count[i] = kept;
  }
  // The touching pairs' other inputs (a second pass over the kept slots: with the full list
  // about a third of the entries do not touch).
  if constexpr (kMode != PruneMode::Use) {
    for (std::size_t m = n_first; m < n; ++m) {
      write_motion_inputs<Model, kCap>(L, in, m, slot_entry[m], pi.r, vi, L.V[slot_partner[m]]);
    }
  }
  // A particle without touching pairs adds +0 to sums that start at +0 or are nonzero: it is
  // left out, so that owners never outnumber contacts.
  if (n > n_first) {
    b.owner[b.owners] = static_cast<NeighborList::Index>(i);
    b.owner_end[b.owners] = static_cast<NeighborList::Index>(n);
    ++b.owners;
  }
  return n;
}

// One column: its particles' pairs in batches of at most PairBatch::kTarget (`batch`, fixed
// size); a particle with more pairs than that (a large grain among fragments) gets a batch of
// its own (`grown`). A grain's pairs are never split between batches, and each contact gets the
// same bits in any batch, so where the batches end changes no result.
template <class Model, PruneMode kMode>
void pair_column(const PairLoopView<Model> L, Idx col, PairBatch& batch, PairBatch& grown) {
  constexpr std::size_t kFixed = PairBatch::kTarget;  // batch.cap
  std::size_t n = 0;
  for (auto k = L.col_off[col]; k < L.col_off[col + 1]; ++k) {
    const std::size_t i = L.col_mem[k];
    // The entries collect_particle() will walk (each needs a slot in the batch).
    const std::size_t degree = kMode == PruneMode::Use ? L.near_count[i] : L.off[i + 1] - L.off[i];
    if (n > 0 && n + degree > kFixed) {
      flush_batch<Model, kFixed>(L, batch, n);
      n = 0;
    }
    if (degree > kFixed) {  // rare
      grown.reserve(degree);
      const std::size_t m = collect_particle<Model, kMode, 0>(L, i, grown, 0);
      flush_batch<Model, 0>(L, grown, m);
      continue;
    }
    n = collect_particle<Model, kMode, kFixed>(L, i, batch, n);
  }
  flush_batch<Model, kFixed>(L, batch, n);
}

}  // namespace

void CpuPairLoop::evaluate(const ContactLaw& law, double h, const ParticleStore& p,
                           const NeighborList& nl, bool prune, ContactHistory& history,
                           ContactLoad* load, double load_factor) {
  with_law(law, [&](const auto& model) {
    evaluate_model(model, h, p, nl, prune, history, load, load_factor);
  });
}

template <class Model>
void CpuPairLoop::evaluate_model(const Model& model, double h, const ParticleStore& p,
                                 const NeighborList& nl, bool prune, ContactHistory& history,
                                 ContactLoad* load, double load_factor) {
  static_assert(Model::kPairHistory <= 2,
                "the pair loop's batches carry the tangential spring and one couple vector");
  const std::size_t N = p.size();
  ContactHistory::Vectors& ft = history.tangential();
  PairLoopView<Model> loop{model.pair_law,
                           model.cp,
                           model.couple,
                           h,
                           nl.offsets.data(),
                           nl.neighbors.data(),
                           nl.column_offsets.data(),
                           nl.column_members.data(),
                           p.x.data(),
                           p.y.data(),
                           p.z.data(),
                           p.radius.data(),
                           p.vx.data(),
                           p.vy.data(),
                           p.vz.data(),
                           p.wx.data(),
                           p.wy.data(),
                           p.wz.data(),
                           ft.x.data(),
                           ft.y.data(),
                           ft.z.data(),
                           history.touching.data()};
  const bool pack = !packed_fresh_ || positions_.size() != N || velocities_.size() != N;
  const bool zero = !sums_zero_ || sums_.size() != N;
  const PruneMode mode = pruned_.begin(nl, prune, pack);
  loop.near = pruned_.entries.data();
  loop.near_count = pruned_.count.data();
  loop.inner_skin = pruned_.inner_skin();
  packed_fresh_ = sums_zero_ = false;  // consumed: the next loop refreshes unless told
  positions_.resize(N);
  velocities_.resize(N);
  loop.P = positions_.data();
  loop.V = velocities_.data();
  loop.IM = p.inv_mass.data();
  sums_.resize(N);
  loop.PF = sums_.data();
  if constexpr (Model::kCouple) {
    ContactHistory::Vectors& couple = history.pair[1];
    loop.chx = couple.x.data();
    loop.chy = couple.y.data();
    loop.chz = couple.z.data();
  }
  if (load != nullptr) {
    for (auto* a : {&load->sigma, &load->F_n_max, &load->nx, &load->ny, &load->nz}) {
      a->assign(N, 0.0);
    }
    loop.LS = load->sigma.data();
    loop.LF = load->F_n_max.data();
    loop.LNX = load->nx.data();
    loop.LNY = load->ny.data();
    loop.LNZ = load->nz.data();
    loop.inv_pi_k = 1.0 / (kPi * load_factor);
  }
  const std::vector<NeighborList::Index>& colors = nl.color_offsets;
  const std::uint64_t* work = nl.column_work.data();
  WorkShares& shares = shares_;
  shares.reset(NeighborList::kColors, static_cast<std::size_t>(max_team_size()));
  std::vector<std::unique_ptr<PairBatch>>& batches = batches_.slots;
  if (batches.size() < 2 * static_cast<std::size_t>(max_team_size())) {
    batches.resize(2 * static_cast<std::size_t>(max_team_size()));
  }
#pragma omp parallel if (worth_threading(N))
  {
    const auto threads = static_cast<std::uint64_t>(team_size());
    const auto t = static_cast<std::uint64_t>(thread_index());
    // Each thread's contiguous share of each colour's columns, balanced by their work: columns
    // are in z order and particles in cell order, so a thread keeps to the same slab of the
    // sample in every colour and in the integration loops, and its share of the data stays in
    // its cache. A thread done with its share takes columns from the back of the others'
    // (WorkShares): which thread runs a column does not change any result.
    for (std::size_t color = 0; color < NeighborList::kColors; ++color) {
      const std::uint64_t* first = work + colors[color];
      const std::uint64_t* last = work + colors[color + 1];
      const auto share_start = [&](std::uint64_t k) {
        if (k == threads) return last;
        return std::lower_bound(first, last, *first + (*last - *first) * k / threads);
      };
      shares.set(color, t, static_cast<std::uint32_t>(share_start(t) - work),
                 static_cast<std::uint32_t>(share_start(t + 1) - work));
    }
    // The thread's two batches, made by the thread itself (their pages are then near its core)
    // and kept between steps: their buffers are reused, not reallocated.
    std::unique_ptr<PairBatch>& batch_of_t = batches[2 * t];
    std::unique_ptr<PairBatch>& grown_of_t = batches[2 * t + 1];
    if (!batch_of_t) batch_of_t = std::make_unique<PairBatch>();
    if (!grown_of_t) grown_of_t = std::make_unique<PairBatch>();
    PairBatch& batch = *batch_of_t;
    PairBatch& grown = *grown_of_t;
    batch.reserve(PairBatch::kTarget);
    if (pack || zero) {
#pragma omp for schedule(static)
      for (Idx ii = 0; ii < static_cast<Idx>(N); ++ii) {
        if (zero) loop.PF[ii] = {};
        if (pack) {
          loop.P[ii] = {loop.X[ii], loop.Y[ii], loop.Z[ii], loop.R[ii]};
          loop.V[ii] = {loop.VX[ii], loop.VY[ii], loop.VZ[ii], loop.WX[ii],
                        loop.WY[ii], loop.WZ[ii], loop.IM[ii], 0.0};
        }
      }
    }
    // Colours one after another, with a barrier after each; within a colour, columns never
    // write to the same particle, so both members of a pair are updated directly.
    for (std::size_t color = 0; color < NeighborList::kColors; ++color) {
      std::uint32_t col = 0;
      while (shares.next(color, t, threads, col)) {
        switch (mode) {
          case PruneMode::Use:
            pair_column<Model, PruneMode::Use>(loop, static_cast<Idx>(col), batch, grown);
            break;
          case PruneMode::Build:
            pair_column<Model, PruneMode::Build>(loop, static_cast<Idx>(col), batch, grown);
            break;
          case PruneMode::Full:
            pair_column<Model, PruneMode::Full>(loop, static_cast<Idx>(col), batch, grown);
            break;
        }
      }
#pragma omp barrier
    }
  }
}

detail::PairBatches::PairBatches() = default;
detail::PairBatches::~PairBatches() = default;
detail::PairBatches::PairBatches(const PairBatches& /*other*/) {}
detail::PairBatches& detail::PairBatches::operator=(const PairBatches& /*other*/) {
  return *this;
}
detail::PairBatches::PairBatches(PairBatches&&) noexcept = default;
detail::PairBatches& detail::PairBatches::operator=(PairBatches&&) noexcept = default;

std::size_t CpuPairLoop::memory_bytes() const {
  std::size_t batch_bytes = 0;
  for (const auto& b : batches_.slots) {
    if (b) batch_bytes += sizeof(detail::PairBatch) + b->memory_bytes();
  }
  return positions_.capacity() * sizeof(detail::PackedPosition) +
         velocities_.capacity() * sizeof(detail::PackedVelocity) +
         sums_.capacity() * sizeof(detail::PackedForce) + pruned_.memory_bytes() + batch_bytes;
}

}  // namespace crushdem
