#include "crushdem/integrate/simulation.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>
#include <tuple>
#include <type_traits>

#include "crushdem/contact/contact_kernel.hpp"
#include "crushdem/contact/contact_stress.hpp"
#include "crushdem/core/deterministic.hpp"
#include "crushdem/core/error.hpp"
#include "crushdem/integrate/local_damping.hpp"

namespace crushdem {
namespace {

using Idx = std::ptrdiff_t;

// The first half kick and drift of velocity Verlet for one grain, the pair loop's packed copies
// written from values already in registers, and the two squared-displacement maxima: since the
// last neighbour build (the rebuild criterion) and in this step (the pruned list's). Inlined into
// kick_drift() and into the gather pass of the step before (gather_grains<.., kDrift = true>),
// both loops in vector lanes: each element gets the same operations as a scalar loop, and max()
// is exact, so the lanes change no bit. Constructing it sizes the packed copies to the store.
struct KickDrift {
  double h, hh;
  double spin_scale;  // ContactParams::spin_scale: 0 holds every spin at zero (rotation blocked)
  double *x, *y, *z, *vx, *vy, *vz, *wx, *wy, *wz;
  const double *fx, *fy, *fz, *tx, *ty, *tz, *inv_mass, *inv_inertia, *radius;
  const double *x0, *y0, *z0;  // positions at the last neighbour build
  detail::PackedPosition* P;
  detail::PackedVelocity* V;

  KickDrift(ParticleStore& p, const NeighborList& nl, std::vector<detail::PackedPosition>& pos,
            std::vector<detail::PackedVelocity>& vel, double dt, double spin)
      : h(dt),
        hh(0.5 * dt),
        spin_scale(spin),
        x(p.x.data()),
        y(p.y.data()),
        z(p.z.data()),
        vx(p.vx.data()),
        vy(p.vy.data()),
        vz(p.vz.data()),
        wx(p.wx.data()),
        wy(p.wy.data()),
        wz(p.wz.data()),
        fx(p.fx.data()),
        fy(p.fy.data()),
        fz(p.fz.data()),
        tx(p.tx.data()),
        ty(p.ty.data()),
        tz(p.tz.data()),
        inv_mass(p.inv_mass.data()),
        inv_inertia(p.inv_inertia.data()),
        radius(p.radius.data()),
        x0(nl.x_ref().data()),
        y0(nl.y_ref().data()),
        z0(nl.z_ref().data()) {
    pos.resize(p.size());
    vel.resize(p.size());
    P = pos.data();
    V = vel.data();
  }

  // F and T: the force and torque on the grain (p.fx ... p.tz, or the same values still in
  // registers when fused with the gather pass).
  void operator()(std::size_t i, double Fx, double Fy, double Fz, double Tx, double Ty, double Tz,
                  double& since_build2, double& step2) const {
    constexpr double kInf = std::numeric_limits<double>::infinity();
    const double im = inv_mass[i];
    const double a = hh * im, b = spin_scale * (hh * inv_inertia[i]);
    const double vx1 = vx[i] + a * Fx;
    const double vy1 = vy[i] + a * Fy;
    const double vz1 = vz[i] + a * Fz;
    const double wx1 = spin_scale * wx[i] + b * Tx;
    const double wy1 = spin_scale * wy[i] + b * Ty;
    const double wz1 = spin_scale * wz[i] + b * Tz;
    const double x1 = x[i] + h * vx1;
    const double y1 = y[i] + h * vy1;
    const double z1 = z[i] + h * vz1;
    vx[i] = vx1;
    vy[i] = vy1;
    vz[i] = vz1;
    wx[i] = wx1;
    wy[i] = wy1;
    wz[i] = wz1;
    x[i] = x1;
    y[i] = y1;
    z[i] = z1;
    // The step's displacement is taken from the position the last pair loop saw (its packed
    // copy), so a position set by hand between steps counts too; a changed radius makes it
    // infinite (a copy not yet made has radius 0).
    const detail::PackedPosition seen = P[i];
    const double r = radius[i];
    const double sx = x1 - seen.x, sy = y1 - seen.y, sz = z1 - seen.z;
    const double s2 = sx * sx + sy * sy + sz * sz;
    const double s2_checked = s2 == s2 && seen.r == r ? s2 : kInf;
    step2 = step2 < s2_checked ? s2_checked : step2;
    P[i] = {x1, y1, z1, r};
    V[i] = {vx1, vy1, vz1, wx1, wy1, wz1, im, 0.0};
    const double dx = x1 - x0[i], dy = y1 - y0[i], dz = z1 - z0[i];
    const double d2 = dx * dx + dy * dy + dz * dz;
    // A NaN must not be lost by max(): make it infinite so the rebuild (and its check) runs.
    const double d2_checked = d2 == d2 ? d2 : kInf;
    since_build2 = since_build2 < d2_checked ? d2_checked : since_build2;
  }
};

}  // namespace

void DampingConfig::validate() const {
  validate_params(*this, damping_params(), "damping");
}

void TimestepConfig::validate() const {
  validate_params(*this, timestep_params(), "timestep");
}

void NeighborConfig::validate() const {
  validate_params(*this, neighbor_params(), "neighbor");
}

const ParamTable<DampingConfig>& damping_params() {
  using D = DampingConfig;
  static const ParamTable<D> table = {
      {"local_alpha", &D::local_alpha, "-",
       "PFC local damping: each force and torque component F_j -= alpha |F_j| sign(v_j); 0 = off "
       "(CHOICE)",
       [](double v) { return v >= 0.0 && v < 1.0; }, "a value in [0, 1)"},
  };
  return table;
}

const ParamTable<TimestepConfig>& timestep_params() {
  using T = TimestepConfig;
  static const ParamTable<T> table = {
      {"dt", &T::dt, "s", "fixed time step; 0 = automatic", [](double v) { return v >= 0.0; },
       "a step >= 0 in s (0 = automatic)"},
      {"rayleigh_fraction", &T::rayleigh_fraction, "-",
       "automatic: dt <= fraction x Rayleigh time of the smallest grain",
       [](double v) { return v > 0.0 && v <= 1.0; }, "a value in (0, 1]"},
      {"safety", &T::safety, "-",
       "automatic: dt <= safety x min_i sqrt(m_i / sum of k_n + k_t of its contacts)",
       [](double v) { return v > 0.0 && v <= 1.0; }, "a value in (0, 1]"},
      {"update_interval", &T::update_interval, "", "automatic: steps between re-evaluations",
       [](double v) { return v > 0.0; }, "a positive number of steps"},
  };
  return table;
}

const ParamTable<NeighborConfig>& neighbor_params() {
  using N = NeighborConfig;
  static const ParamTable<N> table = {
      {"skin", &N::skin, "m", "Verlet skin; 0 = half the smallest radius at the first build",
       [](double v) { return v >= 0.0; }, "a skin >= 0 in m (0 = automatic)"},
      {"sort_particles", &N::sort_particles, "",
       "reorder particles in cell order at each rebuild (speed only; results stay "
       "deterministic)"},
      {"prune", &N::prune, "",
       "the pair loop walks a pruned copy of the list: the pairs with a gap below an inner skin "
       "chosen from the grains' speed, remade when they have moved half of it (speed only; "
       "results bit-identical with it off)"},
  };
  return table;
}

void SimulationConfig::validate() const {
  material.validate();
  contact.validate();
  damping.validate();
  timestep.validate();
  neighbor.validate();
  for (int k = 0; k < kNumWalls; ++k) {
    walls[static_cast<std::size_t>(k)].validate(std::string("walls.") + wall_name(k));
  }
  for (int a = 0; a < 3; ++a) {
    const double lo = walls[static_cast<std::size_t>(2 * a)].position;
    const double hi = walls[static_cast<std::size_t>(2 * a + 1)].position;
    if (!(hi > lo)) {
      std::string idx = "[0]";
      idx[1] = static_cast<char>('0' + a);
      throw ConfigError(bad_value("box.max" + idx, show_number(hi),
                                  "a value above box.min" + idx + " = " + show_number(lo)));
    }
  }
}

Simulation::Simulation(const SimulationConfig& cfg) : cfg_(cfg) {
  cfg_.validate();
  cp_ = make_contact_params(cfg_.material, cfg_.contact);
  walls_ = Walls(cfg_.walls);
  skin_ = cfg_.neighbor.skin;
  if (cfg_.timestep.dt > 0.0) {
    dt_ = cfg_.timestep.dt;
    dt_fixed_ = true;
  }
}

ParticleId Simulation::add_particle(Vec3 position, double radius, Vec3 velocity,
                                    Vec3 angular_velocity) {
  NewParticle np;
  np.position = position;
  np.velocity = velocity;
  np.angular_velocity = angular_velocity;
  np.radius = radius;
  np.density = cfg_.material.density;
  TopologyChange ch;
  ch.add.push_back(np);
  return apply_topology(ch).front();
}

std::vector<ParticleId> Simulation::add_particles(std::vector<NewParticle> grains) {
  const auto vec = [](const Vec3& v) {
    return "[" + show_number(v.x) + ", " + show_number(v.y) + ", " + show_number(v.z) + "]";
  };
  const Vec3 lo{walls_.position(0), walls_.position(2), walls_.position(4)};
  const Vec3 hi{walls_.position(1), walls_.position(3), walls_.position(5)};
  for (std::size_t i = 0; i < grains.size(); ++i) {
    const NewParticle& g = grains[i];
    const std::string which = "add_particles: grain " + std::to_string(i);
    if (!(g.radius > 0.0) || !std::isfinite(g.radius)) {
      throw ConfigError(which + ": radius " + show_number(g.radius) +
                        " m: expected a positive radius in m");
    }
    const Vec3& x = g.position;
    const Vec3& v = g.velocity;
    if (!std::isfinite(x.x + x.y + x.z) || !std::isfinite(v.x + v.y + v.z)) {
      throw ConfigError(which + ": expected finite positions and velocities (got centre " + vec(x) +
                        " m, velocity " + vec(v) + " m/s)");
    }
    const double reach = 0.9 * g.radius;
    if (x.x - reach < lo.x || x.y - reach < lo.y || x.z - reach < lo.z || x.x + reach > hi.x ||
        x.y + reach > hi.y || x.z + reach > hi.z) {
      throw ConfigError(which + " (centre " + vec(x) + " m, radius " + show_number(g.radius) +
                        " m) is not inside the box " + vec(lo) + " - " + vec(hi) +
                        " m: expected every grain between the walls");
    }
    grains[i].density = cfg_.material.density;
  }
  TopologyChange ch;
  ch.add = std::move(grains);
  return apply_topology(ch);
}

// --- contact history keyed by ids --------------------------------------------------------------

void Simulation::capture_pair_vectors(const std::vector<double>& x, const std::vector<double>& y,
                                      const std::vector<double>& z,
                                      std::vector<PairHistory>& out) const {
  out.clear();
  for (std::size_t e = 0; e < x.size(); ++e) {
    if (x[e] == 0.0 && y[e] == 0.0 && z[e] == 0.0) continue;
    const ParticleId ia = p_.id[nl_.owner[e]], ib = p_.id[nl_.neighbors[e]];
    if (ia < ib) {
      out.push_back({ia, ib, x[e], y[e], z[e]});
    } else {
      out.push_back({ib, ia, -x[e], -y[e], -z[e]});
    }
  }
  std::sort(out.begin(), out.end());
}

void Simulation::restore_pair_vectors(const std::vector<PairHistory>& saved, std::vector<double>& x,
                                      std::vector<double>& y, std::vector<double>& z) {
  if (saved.empty()) return;
  const std::size_t M = nl_.neighbors.size();
#pragma omp parallel for schedule(static) if (worth_threading(M))
  for (Idx ee = 0; ee < static_cast<Idx>(M); ++ee) {
    const auto e = static_cast<std::size_t>(ee);
    const ParticleId ia = p_.id[nl_.owner[e]], ib = p_.id[nl_.neighbors[e]];
    const ParticleId a = std::min(ia, ib), b = std::max(ia, ib);
    auto it = std::lower_bound(saved.begin(), saved.end(), PairHistory{a, b, 0, 0, 0});
    if (it != saved.end() && it->a == a && it->b == b) {
      const double s = ia == a ? 1.0 : -1.0;
      x[e] = s * it->x;
      y[e] = s * it->y;
      z[e] = s * it->z;
      touching_[e] = 1;  // makes the force pass clear it if the pair has separated
    }
  }
}

void Simulation::capture_history() {
  if (history_saved_ || !nl_valid_) return;
  capture_pair_vectors(ft_x_, ft_y_, ft_z_, saved_pairs_);
  capture_pair_vectors(mr_x_, mr_y_, mr_z_, saved_rolling_);  // empty without rolling
  saved_walls_.clear();
  for (std::size_t e = 0; e < wc_.size(); ++e) {
    if (wc_.ft_x[e] == 0.0 && wc_.ft_y[e] == 0.0 && wc_.ft_z[e] == 0.0) continue;
    saved_walls_.push_back(
        {p_.id[wc_.particle[e]], wc_.wall[e], wc_.ft_x[e], wc_.ft_y[e], wc_.ft_z[e]});
  }
  std::sort(saved_walls_.begin(), saved_walls_.end(),
            [](const WallHistory& u, const WallHistory& v) {
              return std::tie(u.id, u.wall) < std::tie(v.id, v.wall);
            });
  history_saved_ = true;
}

std::vector<ParticleId> Simulation::apply_topology(const TopologyChange& change) {
  capture_history();  // read with the old indices, before the arrays are compacted
  nl_valid_ = false;
  forces_valid_ = false;
  dt_valid_ = false;
  return p_.apply(change);  // validates everything before changing anything
}

void Simulation::invalidate() {
  capture_history();
  nl_valid_ = false;
  forces_valid_ = false;
  dt_valid_ = false;
}

void Simulation::rebuild_neighbors() {
  const PartScope timed(part_clock_, Part::NeighborSearch);
  capture_history();
  const std::size_t N = p_.size();
  if (skin_ <= 0.0 && N > 0) {
    skin_ = 0.5 * *std::min_element(p_.radius.begin(), p_.radius.end());
  }
  // A non-finite coordinate or a grain entirely outside a wall: the state is no longer a valid
  // sample (checked before sorting, which needs finite coordinates).
  for (std::size_t i = 0; i < N; ++i) {
    const double c[3] = {p_.x[i], p_.y[i], p_.z[i]};
    if (!std::isfinite(c[0]) || !std::isfinite(c[1]) || !std::isfinite(c[2])) {
      throw RuntimeFailure("particle id " + std::to_string(p_.id[i]) +
                           " has a non-finite position at t = " + show_number(time_) +
                           " s (time step too large for the contact stiffness?)");
    }
    for (int k = 0; k < kNumWalls; ++k) {
      const double pos = walls_.position(k);
      const double dist = wall_is_low(k) ? c[wall_axis(k)] - pos : pos - c[wall_axis(k)];
      if (!(dist > -p_.radius[i])) {
        throw RuntimeFailure("particle id " + std::to_string(p_.id[i]) +
                             " left the box through wall " + wall_name(k) +
                             " at t = " + show_number(time_) + " s");
      }
    }
  }
  if (cfg_.neighbor.sort_particles && N > 1) p_.permute(NeighborList::spatial_order(p_, skin_));
  packed_fresh_ = false;  // the packed copies follow the old order

  nl_.build(p_, skin_ > 0.0 ? skin_ : 1.0);
  const std::size_t M = nl_.neighbors.size();
  for (auto* a : {&ft_x_, &ft_y_, &ft_z_}) a->assign(M, 0.0);
  for (auto* a : {&mr_x_, &mr_y_, &mr_z_}) a->assign(rolling() ? M : 0, 0.0);
  touching_.assign(M, 0);

  // Wall candidates, sorted by particle index (CSR).
  std::vector<std::uint32_t> wp;
  std::vector<std::uint8_t> ww;
  wall_offsets_.assign(N + 1, 0);
  for (std::size_t i = 0; i < N; ++i) {
    const double c[3] = {p_.x[i], p_.y[i], p_.z[i]};
    for (int k = 0; k < kNumWalls; ++k) {
      const double pos = walls_.position(k);
      const double dist = wall_is_low(k) ? c[wall_axis(k)] - pos : pos - c[wall_axis(k)];
      if (dist - p_.radius[i] < skin_) {
        wp.push_back(static_cast<std::uint32_t>(i));
        ww.push_back(static_cast<std::uint8_t>(k));
      }
    }
    wall_offsets_[i + 1] = static_cast<std::uint32_t>(wp.size());
  }
  wc_.resize(wp.size());
  wc_.particle = std::move(wp);
  wc_.wall = std::move(ww);

  // Restore tangential (and rolling) history by ids.
  if (history_saved_) {
    restore_pair_vectors(saved_pairs_, ft_x_, ft_y_, ft_z_);
    if (rolling()) restore_pair_vectors(saved_rolling_, mr_x_, mr_y_, mr_z_);
    for (std::size_t e = 0; e < wc_.size(); ++e) {
      const WallHistory key{p_.id[wc_.particle[e]], wc_.wall[e], 0, 0, 0};
      auto it = std::lower_bound(saved_walls_.begin(), saved_walls_.end(), key,
                                 [](const WallHistory& u, const WallHistory& v) {
                                   return std::tie(u.id, u.wall) < std::tie(v.id, v.wall);
                                 });
      if (it != saved_walls_.end() && it->id == key.id && it->wall == key.wall) {
        wc_.ft_x[e] = it->x;
        wc_.ft_y[e] = it->y;
        wc_.ft_z[e] = it->z;
      }
    }
    saved_pairs_.clear();
    saved_rolling_.clear();
    saved_walls_.clear();
    history_saved_ = false;
  }
  walls_.reset_displacements();
  nl_valid_ = true;
}

// --- forces ------------------------------------------------------------------------------------

namespace {

// Everything the pair loop touches, passed by value into the per-column worker so the compiler
// sees plain locals (inside an OpenMP region shared variables are reached through a pointer and
// reloaded after every store, which cost 10 % of the step).
template <class Law>
struct PairLoop {
  Law law;
  ContactParams cp;
  double h;
  const NeighborList::Index *off, *nb, *col_off, *col_mem;
  const double *X, *Y, *Z, *R, *VX, *VY, *VZ, *WX, *WY, *WZ;
  double *ftx, *fty, *ftz;
  std::uint8_t* touch;
  double *mrx = nullptr, *mry = nullptr, *mrz = nullptr;  // rolling moment (Rolling only)
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
  // inputs (the rolling moment's: overwritten by the new one)
  kFTX, kFTY, kFTZ, kMRX, kMRY, kMRZ,
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

// One thread's batch: kBatchFields arrays of `cap` (+ kBatchPad) doubles, plus the entry, partner
// and owner bookkeeping of the scatter pass, and a second set of arrays for the contacts that need
// the exact evaluation (evaluate_batch()).
struct PairBatch {
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
};

// Evaluates contacts 0 .. n-1 of a batch in vector lanes; kFastPath: without the rare steps
// (contact_plane_spring()).
// Not inlined: inlined into evaluate_batch() with a fixed-size batch, GCC sees every column as
// one base plus a constant offset, stops trusting the restrict pointers, and (for the rough
// law) left the loop scalar.
// `law` is the pair loop's law or a variant of it for this batch (evaluate_batch()); by value,
// with cp and h, so that the loop reads them from registers.
template <bool Rolling, bool kFastPath, class LaneLaw, class View>
[[gnu::noinline]] void evaluate_lanes(const LaneLaw law, const ContactParams cp, const double h,
                                      View b, std::size_t n) {
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
  double* __restrict const bMRX = b.f(kMRX);
  double* __restrict const bMRY = b.f(kMRY);
  double* __restrict const bMRZ = b.f(kMRZ);
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
    if constexpr (Rolling) {
      const Vec3 M_r = pair_rolling_moment(
          pc.n, pc.c.k_n, pc.c.F_n, Vec3{bMRX[m], bMRY[m], bMRZ[m]},
          Vec3{bWIX[m], bWIY[m], bWIZ[m]}, Vec3{bWJX[m], bWJY[m], bWJZ[m]}, R_star, cp, h);
      bMRX[m] = M_r.x;
      bMRY[m] = M_r.y;
      bMRZ[m] = M_r.z;
    }
  }
}

// Evaluates a batch: every contact on the fast path, in vector lanes; then the few that need
// the exact path (a sliding contact, a turned contact plane) copied into the second arrays,
// evaluated exactly (also in vector lanes) and copied back. Each contact gets the bits of an
// exact evaluation either way, so the results do not depend on how contacts fall into batches.
// (The rolling moment is exact in the first pass and not evaluated again.)
template <bool Rolling, std::size_t kCap, class LaneLaw>
void evaluate_batch_with(const LaneLaw& law, const ContactParams& cp, double h, PairBatch& b,
                         std::size_t n) {
  const BatchView<kCap> main = b.view<kCap>();
  // Where most contacts slide (shearing, a sample out of equilibrium) the fast path only adds a
  // second evaluation: after a batch with more than a quarter of its contacts on the exact path,
  // the next kExactOnly batches go straight to it. Both paths give the same bits, so which one
  // runs changes no result (and may differ between threads).
  constexpr std::size_t kExactOnly = 64;
  if (b.exact_only > 0) {
    --b.exact_only;
    evaluate_lanes<Rolling, false>(law, cp, h, main, n);
    return;
  }
  evaluate_lanes<Rolling, true>(law, cp, h, main, n);
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
  evaluate_lanes<false, false>(law, cp, h, side, ne);
  for (const BatchField f : kOutputs) {
    const double* from = side.f(f);
    double* to = main.f(f);
    for (std::size_t k = 0; k < ne; ++k) to[lane[k]] = from[k];
  }
}

// Whether any of contacts 0 .. n-1 of a batch may be in the rough law's Hertz regime (p: its
// grain-grain constants), from the collected distances and radii: a vector reduction without
// square roots. (The same test in the collect pass, on scalars, cost more instructions than the
// regime saves: callgrind.)
template <std::size_t kCap>
bool batch_may_reach_hertz(const RoughHertzParams& p, const BatchView<kCap> b, std::size_t n) {
  const double* __restrict const d2 = b.f(kD2);
  const double* __restrict const r_i = b.f(kRI);
  const double* __restrict const r_j = b.f(kRJ);
  int any = 0;
#pragma omp simd reduction(| : any)
  for (std::size_t m = 0; m < n; ++m)
    any |= rough_may_reach_hertz(d2[m], r_i[m] + r_j[m], p) ? 1 : 0;
  return any != 0;
}

// Evaluates a batch with the pair loop's law, or, for the rough law where none of the batch's
// contacts can be in its Hertz regime (a sample at rest under a few MPa: none is), with the law
// that leaves that regime out: the same bits for every contact, without a square root per lane.
template <class Law, bool Rolling, std::size_t kCap>
void evaluate_batch(const PairLoop<Law>& L, PairBatch& b, std::size_t n) {
  if constexpr (std::is_same_v<Law, RoughHertzLaw>) {
    if (!batch_may_reach_hertz(L.law.rough, b.view<kCap>(), n)) {
      evaluate_batch_with<Rolling, kCap>(L.law.without_hertz_regime(), L.cp, L.h, b, n);
      return;
    }
  }
  evaluate_batch_with<Rolling, kCap>(L.law, L.cp, L.h, b, n);
}

// The contact load of one contact (crushing): the largest contact stress on each grain, and the
// largest normal force with its normal. j is safe to write for the same reason as its sums
// (column colouring).
template <class Law, std::size_t kCap>
inline void record_contact_load(const PairLoop<Law>& L, const BatchView<kCap> b, std::size_t m,
                                std::size_t i, std::size_t j) {
  const double F_n = b.f(kFN)[m];
  const Vec3 normal{b.f(kNX)[m], b.f(kNY)[m], b.f(kNZ)[m]};
  const double sig =
      pair_contact_stress(F_n, L.inv_pi_k, pair_R_star(b.f(kRI)[m], b.f(kRJ)[m]), b.f(kDELTA)[m]);
  if (sig > L.LS[i]) L.LS[i] = sig;
  if (sig > L.LS[j]) L.LS[j] = sig;
  if (F_n > L.LF[i]) {
    L.LF[i] = F_n;
    L.LNX[i] = normal.x;
    L.LNY[i] = normal.y;
    L.LNZ[i] = normal.z;
  }
  if (F_n > L.LF[j]) {
    L.LF[j] = F_n;
    L.LNX[j] = -normal.x;
    L.LNY[j] = -normal.y;
    L.LNZ[j] = -normal.z;
  }
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
// Rows k = 0..3 of the 4 x 4 matrix whose columns are a, b, c, d: (a[k], b[k], c[k], d[k]).
inline void transpose4(v4d a, v4d b, v4d c, v4d d, v4d row[4]) {
  const v4d ab_even = __builtin_shufflevector(a, b, 0, 4, 2, 6);  // a0 b0 a2 b2
  const v4d ab_odd = __builtin_shufflevector(a, b, 1, 5, 3, 7);   // a1 b1 a3 b3
  const v4d cd_even = __builtin_shufflevector(c, d, 0, 4, 2, 6);
  const v4d cd_odd = __builtin_shufflevector(c, d, 1, 5, 3, 7);
  row[0] = __builtin_shufflevector(ab_even, cd_even, 0, 1, 4, 5);
  row[1] = __builtin_shufflevector(ab_odd, cd_odd, 0, 1, 4, 5);
  row[2] = __builtin_shufflevector(ab_even, cd_even, 2, 3, 6, 7);
  row[3] = __builtin_shufflevector(ab_odd, cd_odd, 2, 3, 6, 7);
}

// The scatter pass without rolling resistance: each contact's force and torques added to both
// grains' sums (PackedForce: fx fy fz tx | ty tz) and its new history stored, in the collect
// order. Each grain's sums get the same IEEE operations in the same order as a scalar loop
// (x - (-y) is x + y exactly), so the bits do not change; but four contacts at a time are turned
// from the batch's columns into rows, so that a partner's six sums take one 4-wide and one
// 2-wide subtraction instead of six scalar ones.
template <class Law, std::size_t kCap>
void scatter_sums(const PairLoop<Law>& L, PairBatch& pb, std::size_t n) {
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
    store4(sum, load4(sum) + __builtin_shufflevector(F, T, 0, 1, 2, 4));    // fx fy fz tx
    store2(sum + 4, load2(sum + 4) + __builtin_shufflevector(T, T, 1, 2));  // ty tz
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
    const v4d yz_lo = __builtin_shufflevector(ajy, ajz, 0, 4, 1, 5);  // y0 z0 y1 z1
    const v4d yz_hi = __builtin_shufflevector(ajy, ajz, 2, 6, 3, 7);  // y2 z2 y3 z3
    const v2d on_j_yz[4] = {
        __builtin_shufflevector(yz_lo, yz_lo, 0, 1), __builtin_shufflevector(yz_lo, yz_lo, 2, 3),
        __builtin_shufflevector(yz_hi, yz_hi, 0, 1), __builtin_shufflevector(yz_hi, yz_hi, 2, 3)};
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
      for (; m < owner_end[r]; ++m) record_contact_load<Law, kCap>(L, b, m, owner[r], partner[m]);
    }
  }
}

// The scatter pass with rolling resistance (scalar): as scatter_sums(), plus the rolling moment
// on both grains and its new history.
template <class Law, std::size_t kCap>
void scatter_sums_rolling(const PairLoop<Law> L, PairBatch& pb) {
  const BatchView<kCap> b = pb.view<kCap>();
  const double *fx = b.f(kFX), *fy = b.f(kFY), *fz = b.f(kFZ);
  const double *tnx = b.f(kTNX), *tny = b.f(kTNY), *tnz = b.f(kTNZ);
  const double *ai = b.f(kAI), *aj = b.f(kAJ);
  const double *ftx = b.f(kNFTX), *fty = b.f(kNFTY), *ftz = b.f(kNFTZ);
  const double *mrx = b.f(kMRX), *mry = b.f(kMRY), *mrz = b.f(kMRZ);
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
      const Vec3 M_r{mrx[m], mry[m], mrz[m]};
      L.mrx[e] = M_r.x;
      L.mry[e] = M_r.y;
      L.mrz[e] = M_r.z;
      T += M_r;
      L.PF[j].tx -= M_r.x;
      L.PF[j].ty -= M_r.y;
      L.PF[j].tz -= M_r.z;
      if (L.LS) record_contact_load<Law, kCap>(L, b, m, i, j);
    }
    L.PF[i].fx += F.x;
    L.PF[i].fy += F.y;
    L.PF[i].fz += F.z;
    L.PF[i].tx += T.x;
    L.PF[i].ty += T.y;
    L.PF[i].tz += T.z;
  }
}

template <class Law, bool Rolling, std::size_t kCap>
void flush_batch(const PairLoop<Law> L, PairBatch& pb, std::size_t n) {
  evaluate_batch<Law, Rolling, kCap>(L, pb, n);
  if constexpr (Rolling) {
    scatter_sums_rolling<Law, kCap>(L, pb);
  } else {
    scatter_sums<Law, kCap>(L, pb, n);
  }
  pb.owners = 0;
}

// A pair's batch inputs beyond the overlap test: radius of i, relative velocity, spins,
// inverse masses and the history of entry e, into slot m. (A transposed copy, four partners'
// velocity lines turned into columns with vector shuffles, measured 5 % slower on the whole
// step: bench/README.md, session 14.)
template <class Law, bool Rolling, std::size_t kCap>
inline void write_motion_inputs(const PairLoop<Law>& L, const BatchView<kCap> in, std::size_t m,
                                std::size_t e, double r_i, const detail::PackedVelocity& vi,
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
  if constexpr (Rolling) {
    in.f(kMRX)[m] = L.mrx[e];
    in.f(kMRY)[m] = L.mry[e];
    in.f(kMRZ)[m] = L.mrz[e];
  }
}

// Appends the touching pairs of particle i to the batch from slot n on (the batch has room for
// all of i's entries); returns the new fill.
template <class Law, bool Rolling, PruneMode kMode, std::size_t kCap>
std::size_t collect_particle(const PairLoop<Law>& L, std::size_t i, PairBatch& b, std::size_t n) {
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
      if constexpr (Rolling) L.mrx[e] = L.mry[e] = L.mrz[e] = 0.0;
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
      write_motion_inputs<Law, Rolling, kCap>(L, in, n, e, pi.r, vi, L.V[j]);
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
      write_motion_inputs<Law, Rolling, kCap>(L, in, m, slot_entry[m], pi.r, vi,
                                              L.V[slot_partner[m]]);
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
template <class Law, bool Rolling, PruneMode kMode>
void pair_column(const PairLoop<Law> L, Idx col, PairBatch& batch, PairBatch& grown) {
  constexpr std::size_t kFixed = PairBatch::kTarget;  // batch.cap
  std::size_t n = 0;
  for (auto k = L.col_off[col]; k < L.col_off[col + 1]; ++k) {
    const std::size_t i = L.col_mem[k];
    // The entries collect_particle() will walk (each needs a slot in the batch).
    const std::size_t degree = kMode == PruneMode::Use ? L.near_count[i] : L.off[i + 1] - L.off[i];
    if (n > 0 && n + degree > kFixed) {
      flush_batch<Law, Rolling, kFixed>(L, batch, n);
      n = 0;
    }
    if (degree > kFixed) {  // rare
      grown.reserve(degree);
      const std::size_t m = collect_particle<Law, Rolling, kMode, 0>(L, i, grown, 0);
      flush_batch<Law, Rolling, 0>(L, grown, m);
      continue;
    }
    n = collect_particle<Law, Rolling, kMode, kFixed>(L, i, batch, n);
  }
  flush_batch<Law, Rolling, kFixed>(L, batch, n);
}

}  // namespace

template <class Law, bool Rolling>
void Simulation::pair_forces(const Law& law, double h) {
  const std::size_t N = p_.size();
  PairLoop<Law> loop{law,
                     cp_,
                     h,
                     nl_.offsets.data(),
                     nl_.neighbors.data(),
                     nl_.column_offsets.data(),
                     nl_.column_members.data(),
                     p_.x.data(),
                     p_.y.data(),
                     p_.z.data(),
                     p_.radius.data(),
                     p_.vx.data(),
                     p_.vy.data(),
                     p_.vz.data(),
                     p_.wx.data(),
                     p_.wy.data(),
                     p_.wz.data(),
                     ft_x_.data(),
                     ft_y_.data(),
                     ft_z_.data(),
                     touching_.data()};
  const bool pack = !packed_fresh_ || packed_pos_.size() != N || packed_vel_.size() != N;
  const bool zero = !packed_force_zero_ || packed_force_.size() != N;
  const PruneMode mode = prune_.begin(nl_, cfg_.neighbor.prune, pack);
  loop.near = prune_.entries.data();
  loop.near_count = prune_.count.data();
  loop.inner_skin = prune_.inner_skin();
  packed_fresh_ = packed_force_zero_ = false;  // consumed: the next loop refreshes unless told
  packed_pos_.resize(N);
  packed_vel_.resize(N);
  loop.P = packed_pos_.data();
  loop.V = packed_vel_.data();
  loop.IM = p_.inv_mass.data();
  packed_force_.resize(N);
  loop.PF = packed_force_.data();
  if constexpr (Rolling) {
    loop.mrx = mr_x_.data();
    loop.mry = mr_y_.data();
    loop.mrz = mr_z_.data();
  }
  if (load_factor_ > 0.0) {
    for (auto* a : {&load_.sigma, &load_.F_n_max, &load_.nx, &load_.ny, &load_.nz}) {
      a->assign(N, 0.0);
    }
    loop.LS = load_.sigma.data();
    loop.LF = load_.F_n_max.data();
    loop.LNX = load_.nx.data();
    loop.LNY = load_.ny.data();
    loop.LNZ = load_.nz.data();
    loop.inv_pi_k = 1.0 / (kPi * load_factor_);
  }
  const std::vector<NeighborList::Index>& colors = nl_.color_offsets;
  const std::uint64_t* work = nl_.column_work.data();
  WorkShares& shares = pair_shares_;
  shares.reset(NeighborList::kColors, static_cast<std::size_t>(max_team_size()));
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
    // One batch per thread, kept between steps (its buffers are reused, not reallocated).
    thread_local PairBatch batch, grown;
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
            pair_column<Law, Rolling, PruneMode::Use>(loop, static_cast<Idx>(col), batch, grown);
            break;
          case PruneMode::Build:
            pair_column<Law, Rolling, PruneMode::Build>(loop, static_cast<Idx>(col), batch, grown);
            break;
          case PruneMode::Full:
            pair_column<Law, Rolling, PruneMode::Full>(loop, static_cast<Idx>(col), batch, grown);
            break;
        }
      }
#pragma omp barrier
    }
  }
}

template <class Law>
void Simulation::wall_forces(const Law& law, double h) {
  const std::size_t M = wc_.size();
  const ContactParams cp = cp_;
  std::array<Vec3, kNumWalls> n_out{};
  std::array<double, kNumWalls> pos{}, vel{};
  for (int k = 0; k < kNumWalls; ++k) {
    n_out[static_cast<std::size_t>(k)] = walls_.outward_normal(k);
    pos[static_cast<std::size_t>(k)] = walls_.position(k);
    vel[static_cast<std::size_t>(k)] = walls_.state(k).velocity;
  }
  // Chunks of wall entries, each in the pair loop's three passes (collect the touching entries,
  // evaluate them in vector lanes with the same wall_contact() as the GPU, write back): bit for
  // bit a one-by-one loop, which under the rough law was 7 % of a step.
  constexpr std::size_t kChunk = 128;
  const auto chunks = static_cast<Idx>((M + kChunk - 1) / kChunk);
#pragma omp parallel for schedule(static) if (worth_threading(M))
  for (Idx chunk = 0; chunk < chunks; ++chunk) {
    const std::size_t first = static_cast<std::size_t>(chunk) * kChunk;
    const std::size_t last = std::min(M, first + kChunk);
    // clang-format off
    enum : std::size_t { NX, NY, NZ, DIST, DELTA, RAD, MASS, VX, VY, VZ, WX, WY, WZ, UX, UY, UZ,
                         FTX, FTY, FTZ, FX, FY, FZ, TX, TY, TZ, FNW, KN, kFields };
    // clang-format on
    alignas(64) double in[kFields][kChunk];
    std::uint32_t slot_entry[kChunk];
    std::size_t n = 0;
    for (std::size_t e = first; e < last; ++e) {
      const std::size_t i = wc_.particle[e];
      const int k = wc_.wall[e];
      const auto ks = static_cast<std::size_t>(k);
      const double c[3] = {p_.x[i], p_.y[i], p_.z[i]};
      const double dist = wall_is_low(k) ? c[wall_axis(k)] - pos[ks] : pos[ks] - c[wall_axis(k)];
      const double delta = p_.radius[i] - dist;
      if (delta <= 0.0) {
        wc_.ft_x[e] = wc_.ft_y[e] = wc_.ft_z[e] = 0.0;
        wc_.fx[e] = wc_.fy[e] = wc_.fz[e] = wc_.tx[e] = wc_.ty[e] = wc_.tz[e] = 0.0;
        wc_.F_n[e] = wc_.k_n[e] = wc_.delta[e] = 0.0;
        continue;
      }
      const Vec3 nk = n_out[ks];
      const Vec3 u = vel[ks] * nk * (wall_is_low(k) ? -1.0 : 1.0);
      slot_entry[n] = static_cast<std::uint32_t>(e);
      in[NX][n] = nk.x;
      in[NY][n] = nk.y;
      in[NZ][n] = nk.z;
      in[DIST][n] = dist;
      in[DELTA][n] = delta;
      in[RAD][n] = p_.radius[i];
      in[MASS][n] = p_.mass[i];
      in[VX][n] = p_.vx[i];
      in[VY][n] = p_.vy[i];
      in[VZ][n] = p_.vz[i];
      in[WX][n] = p_.wx[i];
      in[WY][n] = p_.wy[i];
      in[WZ][n] = p_.wz[i];
      in[UX][n] = u.x;
      in[UY][n] = u.y;
      in[UZ][n] = u.z;
      in[FTX][n] = wc_.ft_x[e];
      in[FTY][n] = wc_.ft_y[e];
      in[FTZ][n] = wc_.ft_z[e];
      ++n;
    }
    // Named restrict pointers and private copies of the law and parameters, as in
    // evaluate_batch(), or the loop does not vectorise.
    const Law law_private = law;
    const ContactParams cp_private = cp;
    double* __restrict const wNX = in[NX];
    double* __restrict const wNY = in[NY];
    double* __restrict const wNZ = in[NZ];
    double* __restrict const wDIST = in[DIST];
    double* __restrict const wDELTA = in[DELTA];
    double* __restrict const wRAD = in[RAD];
    double* __restrict const wMASS = in[MASS];
    double* __restrict const wVX = in[VX];
    double* __restrict const wVY = in[VY];
    double* __restrict const wVZ = in[VZ];
    double* __restrict const wWX = in[WX];
    double* __restrict const wWY = in[WY];
    double* __restrict const wWZ = in[WZ];
    double* __restrict const wUX = in[UX];
    double* __restrict const wUY = in[UY];
    double* __restrict const wUZ = in[UZ];
    double* __restrict const wFTX = in[FTX];
    double* __restrict const wFTY = in[FTY];
    double* __restrict const wFTZ = in[FTZ];
    double* __restrict const wFX = in[FX];
    double* __restrict const wFY = in[FY];
    double* __restrict const wFZ = in[FZ];
    double* __restrict const wTX = in[TX];
    double* __restrict const wTY = in[TY];
    double* __restrict const wTZ = in[TZ];
    double* __restrict const wFNW = in[FNW];
    double* __restrict const wKN = in[KN];
#pragma omp simd
    for (std::size_t m = 0; m < n; ++m) {
      const WallContact wcon = wall_contact(
          law_private, Vec3{wNX[m], wNY[m], wNZ[m]}, wDIST[m], wDELTA[m], wRAD[m], wMASS[m],
          Vec3{wVX[m], wVY[m], wVZ[m]}, Vec3{wWX[m], wWY[m], wWZ[m]}, Vec3{wUX[m], wUY[m], wUZ[m]},
          Vec3{wFTX[m], wFTY[m], wFTZ[m]}, cp_private, h);
      wFTX[m] = wcon.c.F_t.x;
      wFTY[m] = wcon.c.F_t.y;
      wFTZ[m] = wcon.c.F_t.z;
      wFX[m] = wcon.c.force.x;
      wFY[m] = wcon.c.force.y;
      wFZ[m] = wcon.c.force.z;
      wTX[m] = wcon.torque.x;
      wTY[m] = wcon.torque.y;
      wTZ[m] = wcon.torque.z;
      wFNW[m] = wcon.F_n_wall;
      wKN[m] = wcon.c.k_n;
    }
    for (std::size_t m = 0; m < n; ++m) {
      const std::size_t e = slot_entry[m];
      wc_.ft_x[e] = in[FTX][m];
      wc_.ft_y[e] = in[FTY][m];
      wc_.ft_z[e] = in[FTZ][m];
      wc_.fx[e] = in[FX][m];
      wc_.fy[e] = in[FY][m];
      wc_.fz[e] = in[FZ][m];
      wc_.tx[e] = in[TX][m];
      wc_.ty[e] = in[TY][m];
      wc_.tz[e] = in[TZ][m];
      wc_.F_n[e] = in[FNW][m];
      wc_.k_n[e] = in[KN][m];
      wc_.delta[e] = in[DELTA][m];
    }
  }
  // Wall totals in entry order (deterministic; wall entries are few).
  for (int k = 0; k < kNumWalls; ++k) {
    WallState& s = walls_.state(k);
    s.normal_force = 0.0;
    s.force = {};
    s.stiffness = 0.0;
  }
  for (std::size_t e = 0; e < M; ++e) {
    WallState& s = walls_.state(wc_.wall[e]);
    s.normal_force += wc_.F_n[e];
    s.force -= Vec3{wc_.fx[e], wc_.fy[e], wc_.fz[e]};
    s.stiffness += wc_.k_n[e];
  }
}

void Simulation::gather_and_damp(bool kick, bool drift_next) {
  const std::size_t N = p_.size();
  fu_x_.resize(N);
  fu_y_.resize(N);
  fu_z_.resize(N);
  const bool damp = cfg_.damping.local_alpha > 0.0;
  if (drift_next) {
    next_drift_ = damp ? gather_grains<true, true, true>() : gather_grains<false, true, true>();
    packed_fresh_ = true;
  } else if (damp) {
    kick ? gather_grains<true, true, false>() : gather_grains<true, false, false>();
  } else {
    kick ? gather_grains<false, true, false>() : gather_grains<false, false, false>();
  }
  packed_force_zero_ = true;
}

template <bool kDamp, bool kKick, bool kDrift>
Simulation::Drift Simulation::gather_grains() {
  static_assert(kKick || !kDrift, "the next step's kick follows this one's");
  const std::size_t N = p_.size();
  if (N == 0) return {0.0, 0.0};
  const double alpha = cfg_.damping.local_alpha;
  // The sums as a plain array of doubles, eight per grain: GCC vectorises strided access to
  // doubles, not to the fields of an over-aligned struct.
  static_assert(sizeof(detail::PackedForce) == 8 * sizeof(double));
  double* const PF = &packed_force_.data()->fx;
  // The store's velocities, inverse masses and inertias through KickDrift's pointers; plain
  // pointers, not restrict ones, since KickDrift also writes the velocities. `omp simd` lets
  // the loop run in vector lanes anyway, each element with the same operations as a scalar
  // loop. kDrift: the next step's first half kick and drift, in the same pass (step() asks for
  // it when nothing changes between the two steps: same dt, no caller in between).
  const KickDrift kd(p_, nl_, packed_pos_, packed_vel_, dt_, cp_.spin_scale);
  double* const fux = fu_x_.data();
  double* const fuy = fu_y_.data();
  double* const fuz = fu_z_.data();
  double* const pfx = p_.fx.data();
  double* const pfy = p_.fy.data();
  double* const pfz = p_.fz.data();
  double* const ptx = p_.tx.data();
  double* const pty = p_.ty.data();
  double* const ptz = p_.tz.data();
  const std::uint32_t* const wall_first = wall_offsets_.data();
  double m2 = 0.0, step2 = 0.0;
#pragma omp parallel reduction(max : m2, step2) if (worth_threading(N))
  {
    const Share share = static_share(N, static_cast<std::size_t>(team_size()),
                                     static_cast<std::size_t>(thread_index()));
    // The wall contacts of this thread's grains first (few; stored by grain, so each grain's in
    // the order the per-grain loop used to add them): sum + w1 + w2 rounds the same whether the
    // sum is in a register or in memory. The loop over the grains then has no inner loop and
    // runs in vector lanes. (Each thread adds its own grains' walls: a serial pass would pull
    // half the sums from the other core's cache and back.)
    for (std::size_t e = wall_first[share.first]; e < wall_first[share.last]; ++e) {
      double* const sum = PF + 8 * std::size_t{wc_.particle[e]};
      sum[0] += wc_.fx[e];
      sum[1] += wc_.fy[e];
      sum[2] += wc_.fz[e];
      sum[3] += wc_.tx[e];
      sum[4] += wc_.ty[e];
      sum[5] += wc_.tz[e];
    }
#pragma omp simd reduction(max : m2, step2)
    for (std::size_t j = share.first; j < share.last; ++j) {
      double* const sum = PF + 8 * j;
      Vec3 F{sum[0], sum[1], sum[2]};
      Vec3 T{sum[3], sum[4], sum[5]};
      for (int k = 0; k < 8; ++k) sum[k] = 0.0;  // ready for the next pair loop (line in cache)
      fux[j] = F.x;
      fuy[j] = F.y;
      fuz[j] = F.z;
      if constexpr (kDamp) {
        F = {local_damping(F.x, kd.vx[j], alpha), local_damping(F.y, kd.vy[j], alpha),
             local_damping(F.z, kd.vz[j], alpha)};
        T = {local_damping(T.x, kd.wx[j], alpha), local_damping(T.y, kd.wy[j], alpha),
             local_damping(T.z, kd.wz[j], alpha)};
      }
      pfx[j] = F.x;
      pfy[j] = F.y;
      pfz[j] = F.z;
      ptx[j] = T.x;
      pty[j] = T.y;
      ptz[j] = T.z;
      if constexpr (kKick) {  // second half kick of velocity Verlet (one pass over memory)
        const double a = kd.hh * kd.inv_mass[j];
        const double b = kd.spin_scale * (kd.hh * kd.inv_inertia[j]);
        kd.vx[j] += a * F.x;
        kd.vy[j] += a * F.y;
        kd.vz[j] += a * F.z;
        kd.wx[j] = kd.spin_scale * kd.wx[j] + b * T.x;
        kd.wy[j] = kd.spin_scale * kd.wy[j] + b * T.y;
        kd.wz[j] = kd.spin_scale * kd.wz[j] + b * T.z;
      }
      if constexpr (kDrift) kd(j, F.x, F.y, F.z, T.x, T.y, T.z, m2, step2);
    }
  }
  return {m2, step2};
}

void Simulation::compute_forces() {
  // Evaluating forces advances the tangential history by one increment, so it is done once per
  // state: a second call without a step in between does nothing.
  if (forces_valid_ && nl_valid_) return;
  if (!nl_valid_) rebuild_neighbors();
  if (dt_ <= 0.0) dt();
  // A refresh of the current state (start, or after a topology change): the tangential history
  // already holds this step's increment, so none is added (increment time 0).
  evaluate_forces(0.0, false);
}

void Simulation::evaluate_forces(double increment_dt, bool kick, bool drift_next) {
  const PartScope timed(part_clock_, Part::ContactForces);
  // Rolling resistance is a template flag, so the loops without it carry none of its cost.
  if (cfg_.contact.law == NormalLaw::Hertz) {
    const HertzLaw law{cp_.E_star};
    rolling() ? pair_forces<HertzLaw, true>(law, increment_dt)
              : pair_forces<HertzLaw, false>(law, increment_dt);
    wall_forces(law, increment_dt);
  } else {
    const RoughHertzLaw law_pp{cp_.E_star, cp_.rough_pp};
    rolling() ? pair_forces<RoughHertzLaw, true>(law_pp, increment_dt)
              : pair_forces<RoughHertzLaw, false>(law_pp, increment_dt);
    wall_forces(RoughHertzLaw{cp_.E_star, cp_.rough_pw}, increment_dt);
  }
  if (load_factor_ > 0.0) {
    // Wall contacts (few; in entry order): R* = R for a wall, the normal points into the wall.
    for (std::size_t e = 0; e < wc_.size(); ++e) {
      if (wc_.delta[e] <= 0.0) continue;
      const std::size_t i = wc_.particle[e];
      const double F_el = normal_force(wc_.delta[e], p_.radius[i], true).F_n;  // no dashpot
      const double sig = contact_stress(F_el, load_factor_ * p_.radius[i], wc_.delta[e]);
      if (sig > load_.sigma[i]) load_.sigma[i] = sig;
      if (F_el > load_.F_n_max[i]) {
        const Vec3 n = walls_.outward_normal(wc_.wall[e]);
        load_.F_n_max[i] = F_el;
        load_.nx[i] = n.x;
        load_.ny[i] = n.y;
        load_.nz[i] = n.z;
      }
    }
  }
  gather_and_damp(kick, drift_next);
  forces_valid_ = true;
}

void Simulation::track_contact_load(double r_prime_factor) {
  if (!(r_prime_factor >= 0.0) || !std::isfinite(r_prime_factor)) {
    throw ConfigError(bad_value("r_prime_factor", show_number(r_prime_factor), "a factor >= 0"));
  }
  load_factor_ = r_prime_factor;
  forces_valid_ = false;  // the next evaluation fills the load arrays
}

// --- checkpoints -------------------------------------------------------------------------------

void Simulation::save_state(StateWriter& out) const {
  out.tag("simulation");
  p_.save_state(out);
  nl_.save_state(out);
  walls_.save_state(out);
  wc_.save_state(out);
  out.tag("entries");
  for (const auto* a : {&ft_x_, &ft_y_, &ft_z_, &fu_x_, &fu_y_, &fu_z_}) out.put(*a);
  // Formerly the per-entry R*, m* and sqrt(R*) caches: kept empty so that the format (and old
  // checkpoints) stay readable.
  const std::vector<double> none;
  for (int k = 0; k < 3; ++k) out.put(none);
  out.put(touching_);
  out.put(wall_offsets_);
  out.put(saved_pairs_);
  out.put(saved_walls_);
  out.tag("clock");
  out.put(history_saved_);
  out.put(skin_);
  out.put(dt_);
  out.put(dt_fixed_);
  out.put(dt_computed_at_);
  out.put(dt_valid_);
  out.put(forces_valid_);
  out.put(nl_valid_);
  out.put(time_);
  out.put(steps_);
  // cp_ holds tables (pointers) built from the configuration: only its friction can change.
  out.put(cfg_.material.friction);
  out.put(cp_.mu);
  out.put(load_factor_);
  for (const auto* a : {&load_.sigma, &load_.F_n_max, &load_.nx, &load_.ny, &load_.nz}) {
    out.put(*a);
  }
  out.tag("rolling");  // format 3
  for (const auto* a : {&mr_x_, &mr_y_, &mr_z_}) out.put(*a);
  out.put(saved_rolling_);
}

void Simulation::load_state(StateReader& in) {
  in.tag("simulation");
  p_.load_state(in);
  nl_.load_state(in);
  walls_.load_state(in);
  wc_.load_state(in);
  in.tag("entries");
  for (auto* a : {&ft_x_, &ft_y_, &ft_z_, &fu_x_, &fu_y_, &fu_z_}) in.get(*a);
  std::vector<double> unused;  // R*, m* and sqrt(R*) caches of older builds (derived values)
  for (int k = 0; k < 3; ++k) in.get(unused);
  in.get(touching_);
  in.get(wall_offsets_);
  in.get(saved_pairs_);
  in.get(saved_walls_);
  in.tag("clock");
  in.get(history_saved_);
  in.get(skin_);
  in.get(dt_);
  in.get(dt_fixed_);
  in.get(dt_computed_at_);
  in.get(dt_valid_);
  in.get(forces_valid_);
  in.get(nl_valid_);
  in.get(time_);
  in.get(steps_);
  in.get(cfg_.material.friction);
  in.get(cp_.mu);
  in.get(load_factor_);
  for (auto* a : {&load_.sigma, &load_.F_n_max, &load_.nx, &load_.ny, &load_.nz}) in.get(*a);
  if (in.version() >= 3) {
    in.tag("rolling");
    for (auto* a : {&mr_x_, &mr_y_, &mr_z_}) in.get(*a);
    in.get(saved_rolling_);
  } else {
    // Older checkpoints predate rolling resistance, so their configuration has it off.
    for (auto* a : {&mr_x_, &mr_y_, &mr_z_}) a->clear();
    saved_rolling_.clear();
  }
  if (rolling() && nl_valid_ && mr_x_.size() != nl_.neighbors.size()) {
    throw RuntimeFailure("checkpoint: rolling-resistance history and neighbour list disagree");
  }
  if (nl_valid_ && nl_.num_particles() != p_.size()) {
    throw RuntimeFailure("checkpoint: neighbour list and particles disagree");
  }
  // The loaded list may carry the build count the pruned list was made for.
  prune_.invalidate();
}

// --- time integration --------------------------------------------------------------------------

void Simulation::set_friction(double mu) {
  if (!(mu >= 0.0) || !std::isfinite(mu)) {
    throw ConfigError(bad_value("friction", show_number(mu), "a coefficient >= 0"));
  }
  cfg_.material.friction = mu;
  cp_.mu = mu;
}

Simulation::Drift Simulation::kick_drift() {
  // First half kick and drift in one pass (KickDrift), with the displacement maxima.
  const std::size_t N = p_.size();
  const KickDrift kd(p_, nl_, packed_pos_, packed_vel_, dt_, cp_.spin_scale);
  double m2 = 0.0, step2 = 0.0;
#pragma omp parallel for simd schedule(static) reduction(max : m2, step2) if (worth_threading(N))
  for (Idx ii = 0; ii < static_cast<Idx>(N); ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    kd(i, kd.fx[i], kd.fy[i], kd.fz[i], kd.tx[i], kd.ty[i], kd.tz[i], m2, step2);
  }
  packed_fresh_ = true;
  return {m2, step2};
}

void Simulation::step(std::uint64_t n) {
  // Integration unless a rebuild or the force evaluation (their own parts) is running.
  const PartScope timed(part_clock_, Part::Integration);
  for (std::uint64_t s = 0; s < n; ++s) {
    dt();
    if (!forces_valid_ || !nl_valid_) compute_forces();
    const double h = dt_;
    // The first half kick and drift, unless the last step's gather pass did it already.
    const Drift drift = next_drift_ ? *next_drift_ : kick_drift();
    next_drift_.reset();
    prune_.add_step(std::sqrt(drift.step2));
    const double d = std::sqrt(drift.since_build2);
    walls_.move(h);
    if (rebuild_due(d, walls_.max_displacement_since_build(), skin_)) rebuild_neighbors();
    // The next step's kick and drift join this step's gather pass (one pass over the grains
    // instead of two) when that step follows in this call, with the same dt: nothing outside
    // step() can change the state in between, and dt() will not recompute it.
    evaluate_forces(h, true, s + 1 < n && !dt_due(steps_ + 1));
    walls_.update_velocities(h);
    time_ += h;
    ++steps_;
  }
}

double Simulation::rayleigh_dt() const {
  // T_R = pi r sqrt(rho / G) / (0.1631 nu + 0.8766), smallest over the grains (each its own
  // density: fragments or density-scaled grains may differ).
  if (p_.size() == 0) return std::numeric_limits<double>::infinity();
  double r_sqrt_rho = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < p_.size(); ++i) {
    const double r = p_.radius[i];
    const double rho = p_.mass[i] / (4.0 / 3.0 * kPi * r * r * r);
    r_sqrt_rho = std::min(r_sqrt_rho, r * std::sqrt(rho));
  }
  const double G = cfg_.material.shear_modulus, nu = cfg_.material.poisson_ratio;
  return kPi * r_sqrt_rho / std::sqrt(G) / (0.1631 * nu + 0.8766);
}

NormalForce Simulation::normal_force(double delta, double R_star, bool wall) const {
  if (cfg_.contact.law == NormalLaw::Hertz) return hertz_normal(delta, R_star, cp_.E_star);
  return rough_hertz_normal(delta, R_star, cp_.E_star, wall ? cp_.rough_pw : cp_.rough_pp);
}

double Simulation::stiffness_dt() const {
  // min_i sqrt(m_i / sum k_i) over grains with contacts, k = k_n + k_t of each contact.
  const std::size_t N = p_.size();
  if (!nl_valid_ || N == 0) return std::numeric_limits<double>::infinity();
  std::vector<double> ksum(N, 0.0);
  const double kt_ratio = 1.0 + cp_.tangential_ratio;
  for (std::size_t i = 0; i < N; ++i) {
    for (auto e = nl_.offsets[i]; e < nl_.offsets[i + 1]; ++e) {
      const auto j = nl_.neighbors[e];
      const double dx = p_.x[j] - p_.x[i], dy = p_.y[j] - p_.y[i], dz = p_.z[j] - p_.z[i];
      const double delta = p_.radius[i] + p_.radius[j] - std::sqrt(dx * dx + dy * dy + dz * dz);
      if (delta <= 0.0) continue;
      const double k =
          kt_ratio * normal_force(delta, pair_R_star(p_.radius[i], p_.radius[j]), false).k_n;
      ksum[i] += k;
      ksum[j] += k;
    }
  }
  for (std::size_t e = 0; e < wc_.size(); ++e) {
    const std::size_t i = wc_.particle[e];
    const int k = wc_.wall[e];
    const double c[3] = {p_.x[i], p_.y[i], p_.z[i]};
    const double pos = walls_.position(k);
    const double delta =
        p_.radius[i] - (wall_is_low(k) ? c[wall_axis(k)] - pos : pos - c[wall_axis(k)]);
    if (delta > 0.0) ksum[i] += kt_ratio * normal_force(delta, p_.radius[i], true).k_n;
  }
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < N; ++i) {
    if (ksum[i] > 0.0) best = std::min(best, std::sqrt(p_.mass[i] / ksum[i]));
  }
  return best;
}

bool Simulation::dt_due(std::uint64_t step) const {
  return !dt_fixed_ && (!dt_valid_ || step - dt_computed_at_ >= cfg_.timestep.update_interval);
}

double Simulation::automatic_dt() {
  if (!nl_valid_ && p_.size() > 0) rebuild_neighbors();
  const double h = std::min(cfg_.timestep.rayleigh_fraction * rayleigh_dt(),
                            cfg_.timestep.safety * stiffness_dt());
  return std::isfinite(h) ? h : 1e-6;  // no particles: any value works
}

double Simulation::dt() {
  if (dt_due(steps_)) {
    dt_ = automatic_dt();
    dt_valid_ = true;
    dt_computed_at_ = steps_;
  }
  return dt_;
}

void Simulation::set_dt(double dt) {
  if (!(dt > 0.0) || !std::isfinite(dt)) {
    throw ConfigError(bad_value("timestep.dt", show_number(dt), "a positive time step in s"));
  }
  dt_ = dt;
  dt_fixed_ = true;
}

// --- measurements ------------------------------------------------------------------------------

double Simulation::kinetic_energy() const {
  return deterministic_sum(p_.size(), [&](std::size_t i) {
    const double v2 = p_.vx[i] * p_.vx[i] + p_.vy[i] * p_.vy[i] + p_.vz[i] * p_.vz[i];
    const double w2 = p_.wx[i] * p_.wx[i] + p_.wy[i] * p_.wy[i] + p_.wz[i] * p_.wz[i];
    return 0.5 * p_.mass[i] * v2 + 0.5 / p_.inv_inertia[i] * w2;
  });
}

std::size_t Simulation::memory_bytes() const {
  std::size_t b = 0;
  auto add = [&b](const auto& v) { b += v.capacity() * sizeof(v[0]); };
  for (const auto* v :
       {&p_.x, &p_.y, &p_.z, &p_.vx, &p_.vy, &p_.vz, &p_.wx, &p_.wy, &p_.wz, &p_.fx, &p_.fy, &p_.fz,
        &p_.tx, &p_.ty, &p_.tz, &p_.radius, &p_.mass, &p_.inv_mass, &p_.inv_inertia}) {
    add(*v);
  }
  add(p_.id);
  add(p_.parent);
  for (std::size_t k = 0; k < p_.field_names().size(); ++k) add(p_.field(k));
  for (const auto* v : {&nl_.offsets, &nl_.neighbors, &nl_.column_offsets, &nl_.column_members,
                        &nl_.owner, &wall_offsets_}) {
    add(*v);
  }
  for (const auto* v : {&ft_x_, &ft_y_, &ft_z_, &mr_x_, &mr_y_, &mr_z_}) {
    add(*v);
  }
  add(touching_);
  add(packed_pos_);
  add(packed_vel_);
  add(packed_force_);
  b += prune_.memory_bytes();
  add(wc_.particle);
  add(wc_.wall);
  for (const auto* v : {&wc_.ft_x, &wc_.ft_y, &wc_.ft_z, &wc_.fx, &wc_.fy, &wc_.fz, &wc_.tx,
                        &wc_.ty, &wc_.tz, &wc_.F_n, &wc_.k_n, &wc_.delta}) {
    add(*v);
  }
  return b;
}

std::size_t Simulation::num_contacts() const {
  std::size_t n = 0;
  if (!forces_valid_) return 0;
  for (auto t : touching_) n += t;
  return n;
}

ContactRecord Simulation::pair_record(std::size_t e) const {
  const std::size_t i = nl_.owner[e], j = nl_.neighbors[e];
  const Vec3 dx{p_.x[j] - p_.x[i], p_.y[j] - p_.y[i], p_.z[j] - p_.z[i]};
  const double dist = norm(dx);
  ContactRecord c;
  c.id_i = p_.id[i];
  c.id_j = p_.id[j];
  c.delta = p_.radius[i] + p_.radius[j] - dist;
  c.normal = (1.0 / dist) * dx;
  c.F_n = normal_force(c.delta, pair_R_star(p_.radius[i], p_.radius[j]), false).F_n;
  c.F_t = {ft_x_[e], ft_y_[e], ft_z_[e]};
  if (!mr_x_.empty()) c.M_r = {mr_x_[e], mr_y_[e], mr_z_[e]};
  return c;
}

std::vector<ContactRecord> Simulation::contacts() const {
  std::vector<ContactRecord> out;
  if (!forces_valid_) return out;
  for (std::size_t e = 0; e < nl_.neighbors.size(); ++e) {
    if (touching_[e]) out.push_back(pair_record(e));
  }
  for (std::size_t e = 0; e < wc_.size(); ++e) {
    if (wc_.delta[e] <= 0.0) continue;
    ContactRecord c;
    c.id_i = p_.id[wc_.particle[e]];
    c.id_j = wc_.wall[e];
    c.is_wall = true;
    c.delta = wc_.delta[e];
    c.normal = walls_.outward_normal(wc_.wall[e]);
    c.F_n = wc_.F_n[e];
    c.F_t = {wc_.ft_x[e], wc_.ft_y[e], wc_.ft_z[e]};
    out.push_back(c);
  }
  return out;
}

std::array<double, 9> Simulation::love_weber_stress() const {
  // sigma_ab = (1/V) sum_c f_a l_b: f the contact force on j (or on the wall), l the branch
  // vector from i to j (or from the grain centre to the wall contact). Elastic contact forces;
  // viscous damping forces (zero at equilibrium) are left out.
  std::array<double, 9> s{};
  if (!forces_valid_) return s;
  const double V = walls_.volume();
  std::vector<std::array<double, 9>> per_entry(nl_.neighbors.size());
#pragma omp parallel for schedule(static) if (worth_threading(per_entry.size()))
  for (Idx ee = 0; ee < static_cast<Idx>(per_entry.size()); ++ee) {
    const auto e = static_cast<std::size_t>(ee);
    per_entry[e] = {};
    if (!touching_[e]) continue;
    const ContactRecord c = pair_record(e);
    const Vec3 f = c.F_n * c.normal - c.F_t;  // force on j
    const Vec3 l = (p_.radius[nl_.owner[e]] + p_.radius[nl_.neighbors[e]] - c.delta) * c.normal;
    const double fa[3] = {f.x, f.y, f.z}, lb[3] = {l.x, l.y, l.z};
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 3; ++b) per_entry[e][static_cast<std::size_t>(3 * a + b)] = fa[a] * lb[b];
    }
  }
  for (std::size_t k = 0; k < 9; ++k) {
    double pair =
        deterministic_sum(per_entry.size(), [&](std::size_t e) { return per_entry[e][k]; });
    double wall = 0.0;
    const int a = static_cast<int>(k / 3), b = static_cast<int>(k % 3);
    for (std::size_t e = 0; e < wc_.size(); ++e) {
      if (wc_.delta[e] <= 0.0) continue;
      const Vec3 n = walls_.outward_normal(wc_.wall[e]);
      const double dist = p_.radius[wc_.particle[e]] - wc_.delta[e];
      const Vec3 f = wc_.F_n[e] * n - Vec3{wc_.ft_x[e], wc_.ft_y[e], wc_.ft_z[e]};  // on the wall
      const double fa[3] = {f.x, f.y, f.z}, lb[3] = {dist * n.x, dist * n.y, dist * n.z};
      wall += fa[a] * lb[b];
    }
    s[k] = (pair + wall) / V;
  }
  return s;
}

}  // namespace crushdem
