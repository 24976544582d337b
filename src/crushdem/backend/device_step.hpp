// One step of the engine as per-thread bodies over a device copy of its state: the code the CUDA
// kernels run (backend/cuda_device.cu) and the host emulation runs serially in the same order of
// summation (backend/device_stepper.cpp), so the two give the same bits. Every physics rule is
// the CPU engine's own: pair_contact() and wall_contact() (contact/contact_kernel.hpp), the
// half kick, drift, NaN rule and damping (integrate/step_rules.hpp), the wall gap, normal and
// servo law (walls/wall_geometry.hpp), the contact-load maxima (contact/contact_stress.hpp) and
// the crushing check with crack growth (fracture/crack_growth.hpp).
//
// A step, as the CUDA stream runs it:
//
//   kick_drift    first half kick and drift per grain, and the largest squared displacement
//                 since the neighbour build (a maximum: exact in any order). The last block
//                 moves the walls and applies the rebuild rule; when a rebuild is due it sets
//                 `halt` and the rest of the step waits for the host (which rebuilds the list,
//                 carrying the history over, and uploads again);
//   contacts      one thread per neighbour entry (contact, new history, touching flag, a
//                 reaction record: force on the owner, torques on owner and partner), then one
//                 per wall entry;
//   gather        one thread per grain: its own entries, the entries where it is the partner in
//                 increasing entry order (a reverse CSR built at upload), its wall entries; the
//                 contact load when tracked; local damping and the second half kick. Six extra
//                 blocks make the wall totals in a fixed tree and set each wall's velocity by the
//                 servo law; thread 0 advances the clock;
//   crushing      at every crushing.interval-th step, one thread per grain: the crushing check
//                 and crack growth; a failure sets `halt` so that the host splits the grain.
//
// No floating-point atomics: every sum has an order fixed by the lists, so runs repeat bit for
// bit. They are not bit-identical to the CPU engine, whose sums run in column order. The GPU and
// the host emulation give the same bits except in crack growth, whose pow() CUDA rounds
// differently from the host's C library (within 2 ulp).
#pragma once

#include <cstdint>
#include <limits>

#include "crushdem/contact/contact_kernel.hpp"
#include "crushdem/contact/contact_stress.hpp"
#include "crushdem/fracture/crack_growth.hpp"
#include "crushdem/integrate/step_rules.hpp"
#include "crushdem/neighbor/neighbor_list.hpp"
#include "crushdem/walls/body_geometry.hpp"
#include "crushdem/walls/wall_geometry.hpp"

namespace crushdem::device {

using Index = std::uint32_t;

constexpr int kBlock = 256;           // threads per block of the per-grain kernels
constexpr int kContactBlock = 128;    // threads per block of the contact kernel
constexpr int kWallThreads = kBlock;  // threads per wall for the wall totals (a power of two)
constexpr int kInspectBlock = 256;    // grains per block of the inspection's first pass
constexpr int kBatchSteps = 100;      // steps per batch (one CUDA graph launch)

/// Room for bodies (the box's six walls included) in the control block and the view: as many
/// as a run may hold (walls/walls.hpp).
constexpr int kMaxDeviceBodies = 16;

/// Why the device stopped before the end of a batch.
enum Halt : int { kRunning = 0, kRebuild = 1, kFailure = 2 };

struct WallDev {
  double position, velocity, normal_force, fx, fy, fz, stiffness, displacement;
};

struct WallCfgDev {
  int mode;  // 0 fixed, 1 velocity, 2 servo
  double velocity, target_stress, servo_alpha, max_speed;
};

/// A share of the inspection's sums (plain: it lives in shared memory).
struct InspectSum {
  double resultant, F_n, pairs;
};

/// The device-resident control block: the clock, the step, the walls and the counters every
/// kernel reads, copied to the host after each batch.
struct Control {
  int halt;                    // Halt: the rest of the batch does nothing
  unsigned steps_done;         // full steps completed since the last upload
  unsigned long long m2_bits;  // bits of the largest squared displacement of this step
  unsigned N, M, Mw;           // grains, neighbour entries, wall entries
  unsigned blocks_done;        // kick_drift blocks finished in this step (last-block ticket)
  unsigned failures;           // grains that failed at the last crushing check (then halt)
  double time;                 // simulated time [s], advanced by h per step as the host does
  unsigned long long steps;    // step count
  double h, hh;                // the step and its half
  double last_check_time;      // time of the last crushing check [s]
  double check_elapsed;        // time since the check before, for crack growth [s]
  // The inspection (the controllers' scalars, reduced on demand): sum over grains of
  // |resultant force|, sum of the elastic F_n of the touching grain pairs, and their count.
  double inspect_resultant, inspect_F_n, inspect_pairs;
  // The stiffness time min_i sqrt(m_i / sum k_i) as the bits of a positive double (a minimum:
  // exact in any order), reduced on demand for the automatic time step.
  unsigned long long stiffness_bits;
  WallDev walls[kMaxDeviceBodies];
};

/// What a device array is counted by.
enum class Count { Grains, Entries, WallEntries, GrainsPlusOne, Bodies };
/// When a run holds it: always, with the contact load tracked (crushing), with the crushing check.
enum class When { Always, Load, Crushing };

// The device's arrays that mirror host arrays of the Simulation, declared once. Each row: the
// View member, its element type, what it is counted by, whether the device writes it (a sync
// downloads it; otherwise the device only reads it), when the run holds it, whether the
// per-entry R*, sqrt(R*) and m* derive from it (a host change then uploads everything), and the
// host array (an expression on `s`, the Simulation, and `crusher`, the run's Crusher; expanded
// by host code only). The View's members and backend/device_stepper.cpp's transfer list both
// come from these rows; the contact history the law declares comes on top (View::ph).
// clang-format off
#define CD_DEVICE_FIELDS(X) \
  /* per grain: position, velocity, spin, force, torque; the resultant before damping */ \
  CD_GRAIN_XYZ(X, ) \
  CD_GRAIN_XYZ(X, v) \
  CD_GRAIN_XYZ(X, w) \
  CD_GRAIN_XYZ(X, f) \
  CD_GRAIN_XYZ(X, t) \
  X(fux, double, Grains, true, Always, false, s.resultant_force(0)) \
  X(fuy, double, Grains, true, Always, false, s.resultant_force(1)) \
  X(fuz, double, Grains, true, Always, false, s.resultant_force(2)) \
  X(radius, double, Grains, false, Always, true, s.particles().radius) \
  X(mass, double, Grains, false, Always, true, s.particles().mass) \
  X(inv_mass, double, Grains, false, Always, true, s.particles().inv_mass) \
  X(inv_inertia, double, Grains, false, Always, false, s.particles().inv_inertia) \
  /* the positions at the last list build */ \
  X(x0, double, Grains, false, Always, false, s.neighbors().x_ref()) \
  X(y0, double, Grains, false, Always, false, s.neighbors().y_ref()) \
  X(z0, double, Grains, false, Always, false, s.neighbors().z_ref()) \
  /* the half list and its touching flags */ \
  X(owner, Index, Entries, false, Always, false, s.neighbors().owner) \
  X(nb, Index, Entries, false, Always, false, s.neighbors().neighbors) \
  X(touch, std::uint8_t, Entries, true, Always, false, s.history().touching) \
  /* wall entries: grain and body; tangential history and the results of the last pass */ \
  X(wp, Index, WallEntries, false, Always, false, s.wall_contacts().particle) \
  X(ww, std::uint8_t, WallEntries, false, Always, false, s.wall_contacts().wall) \
  CD_WALL_XYZ(X, wft, ft_) \
  CD_WALL_XYZ(X, wf, f) \
  CD_WALL_XYZ(X, wt, t) \
  X(wFn, double, WallEntries, true, Always, false, s.wall_contacts().F_n) \
  X(wkn, double, WallEntries, true, Always, false, s.wall_contacts().k_n) \
  X(wdelta, double, WallEntries, true, Always, false, s.wall_contacts().delta) \
  /* the bodies' shapes and the servo areas they were given */ \
  X(shape, BodyShape, Bodies, false, Always, false, s.walls().shapes()) \
  X(body_area, double, Bodies, false, Always, false, s.walls().given_areas()) \
  /* the contact load per grain (both ways: the host's forces fill it too) */ \
  X(LS, double, Grains, true, Load, false, s.contact_load().sigma) \
  X(LF, double, Grains, true, Load, false, s.contact_load().F_n_max) \
  X(LNX, double, Grains, true, Load, false, s.contact_load().nx) \
  X(LNY, double, Grains, true, Load, false, s.contact_load().ny) \
  X(LNZ, double, Grains, true, Load, false, s.contact_load().nz) \
  /* crushing: strengths and crack half-lengths */ \
  X(sigma_lim, double, Grains, false, Crushing, false, \
    s.particles().field(crusher->strength_field())) \
  X(crack_a, double, Grains, true, Crushing, false, s.particles().field(crusher->crack_field()))
// clang-format on

// The three components of a grain vector of the store (prefix p: x, vx, wx, fx, tx ...), both
// ways, and of a wall entry's vector (the device's prefix, the host's).
#define CD_GRAIN_XYZ(X, p)                                         \
  X(p##x, double, Grains, true, Always, false, s.particles().p##x) \
  X(p##y, double, Grains, true, Always, false, s.particles().p##y) \
  X(p##z, double, Grains, true, Always, false, s.particles().p##z)
#define CD_WALL_XYZ(X, dev, host)                                                \
  X(dev##x, double, WallEntries, true, Always, false, s.wall_contacts().host##x) \
  X(dev##y, double, WallEntries, true, Always, false, s.wall_contacts().host##y) \
  X(dev##z, double, WallEntries, true, Always, false, s.wall_contacts().host##z)

// The device-only arrays: what the device derives at an upload or keeps between kernels. Each
// row: the View member, its element type, what it is counted by, when the run holds it.
#define CD_DEVICE_SCRATCH(X)                                                                 \
  /* the list as CSR with N + 1 offsets, its reverse (the entries where a grain is the       \
     partner, in increasing order), per-entry R*, sqrt(R*) and m*, the wall entries' CSR */  \
  X(off, Index, GrainsPlusOne, Always)                                                       \
  X(roff, Index, GrainsPlusOne, Always)                                                      \
  X(rev, Index, Entries, Always)                                                             \
  X(RS, double, Entries, Always)                                                             \
  X(SRS, double, Entries, Always)                                                            \
  X(ME, double, Entries, Always)                                                             \
  X(woff, Index, GrainsPlusOne, Always)                                                      \
  /* reaction records per entry: force on the owner, torques on owner and partner */         \
  X(rfx, double, Entries, Always)                                                            \
  X(rfy, double, Entries, Always)                                                            \
  X(rfz, double, Entries, Always)                                                            \
  X(rix, double, Entries, Always)                                                            \
  X(riy, double, Entries, Always)                                                            \
  X(riz, double, Entries, Always)                                                            \
  X(rjx, double, Entries, Always)                                                            \
  X(rjy, double, Entries, Always)                                                            \
  X(rjz, double, Entries, Always)                                                            \
  /* contact load per pair entry (sigma_c, elastic F_n, normal i -> j) and per wall entry */ \
  X(esig, double, Entries, Load)                                                             \
  X(eFn, double, Entries, Load)                                                              \
  X(enx, double, Entries, Load)                                                              \
  X(eny, double, Entries, Load)                                                              \
  X(enz, double, Entries, Load)                                                              \
  X(wsig, double, WallEntries, Load)                                                         \
  X(wFel, double, WallEntries, Load)                                                         \
  /* failure flags of the last crushing check */                                             \
  X(fail, std::uint8_t, Grains, Crushing)

/// Room for the pair history the contact law declares (ContactModel::kPairHistory at most).
constexpr int kMaxPairHistory = 2;

/// Everything a kernel touches, passed by value: fixed between uploads that do not reallocate
/// or change a parameter (a change makes a new view and, on the GPU, a new graph). An array the
/// run does not hold is null.
struct View {
#define CD_VIEW_FIELD(name, T, count, writes, when, feeds, host) T* name;
#define CD_VIEW_SCRATCH(name, T, count, when) T* name;
  CD_DEVICE_FIELDS(CD_VIEW_FIELD)
  CD_DEVICE_SCRATCH(CD_VIEW_SCRATCH)
#undef CD_VIEW_FIELD
#undef CD_VIEW_SCRATCH
  // The pair history the law declares (ContactLaw::pair_history()), per entry, both ways: vector
  // k's components ph[k][0..2] (ph[0]: the tangential spring force on the owner).
  double* ph[kMaxPairHistory][3];
  double inv_pi_k, load_factor;  // 1 / (pi r'/R*) and r'/R* (contact load)
  // Crushing (with `fail`): crack growth.
  double d_c, v0, n_charles;
  bool crack_growth;
  std::uint64_t crush_interval;  // 0: no crushing check
  InspectSum* inspect_partial;   // one per block of the inspection's first pass
  Control* ctrl;
  // Room in the buffers (grains, pair entries, wall entries): the kernels' grids cover these,
  // so the counts in the control block may change within them.
  unsigned grain_capacity, entry_capacity, wall_entry_capacity;
  unsigned bodies;  // the box's six walls and the bodies beyond
  double alpha, skin;
  Vec3 gravity;  // the weight's acceleration; zero: none (integrate/integrator.hpp)
  bool has_gravity;
  WallCfgDev wcfg[kMaxDeviceBodies];
  ContactParams cp;
};

struct WallSum {  // plain (no initialisers): it lives in shared memory
  double Fn, fx, fy, fz, k;
};

// --- per-thread bodies -------------------------------------------------------------------------

/// First half kick and drift of grain i; returns its squared displacement since the build.
CD_HD inline double kick_drift_item(const View& v, Index i) {
  const double h = v.ctrl->h, hh = v.ctrl->hh;
  half_kick(hh, v.cp.spin_scale, v.inv_mass[i], v.inv_inertia[i], Vec3{v.fx[i], v.fy[i], v.fz[i]},
            Vec3{v.tx[i], v.ty[i], v.tz[i]}, v.vx[i], v.vy[i], v.vz[i], v.wx[i], v.wy[i], v.wz[i]);
  v.x[i] = drifted(v.x[i], h, v.vx[i]);
  v.y[i] = drifted(v.y[i], h, v.vy[i]);
  v.z[i] = drifted(v.z[i], h, v.vz[i]);
  return square_displacement(v.x[i], v.y[i], v.z[i], v.x0[i], v.y0[i], v.z0[i]);
}

/// Walls::move, then the rebuild rule of the CPU step (neighbor/neighbor_list.hpp).
CD_HD inline void finish_drift(const View& v, double m2) {
  Control& c = *v.ctrl;
  double travel = 0.0;
  for (int k = 0; k < static_cast<int>(v.bodies); ++k) {
    WallDev& s = c.walls[k];
    s.position += s.velocity * c.h;
    s.displacement += std::fabs(s.velocity * c.h);
    travel = travel < s.displacement ? s.displacement : travel;
  }
  if (rebuild_due(std::sqrt(m2), travel, v.skin)) c.halt = kRebuild;
}

/// One pair entry with the contact law `model` (a ContactModel: its pair evaluator and couple);
/// the shared parameters come from the view.
template <class Model>
CD_HD inline void pair_item(const View& v, const Model& model, Index e) {
  double* const* ft = v.ph[0];
  const Index i = v.owner[e], j = v.nb[e];
  const Vec3 xi{v.x[i], v.y[i], v.z[i]};
  const double ri = v.radius[i];
  const Vec3 dx{v.x[j] - xi.x, v.y[j] - xi.y, v.z[j] - xi.z};
  const double d2 = dot(dx, dx);
  const double rsum = ri + v.radius[j];
  if (d2 >= rsum * rsum) {
    if (v.touch[e]) {
      v.touch[e] = 0;
      ft[0][e] = ft[1][e] = ft[2][e] = 0.0;
      if constexpr (Model::kCouple) v.ph[1][0][e] = v.ph[1][1][e] = v.ph[1][2][e] = 0.0;
    }
    return;
  }
  const Vec3 wi{v.wx[i], v.wy[i], v.wz[i]};
  const Vec3 wj{v.wx[j], v.wy[j], v.wz[j]};
  const double h = v.ctrl->h;
  const PairContact pc =
      pair_contact(model.pair_law, dx, d2, ri, v.radius[j],
                   Vec3{v.vx[i] - v.vx[j], v.vy[i] - v.vy[j], v.vz[i] - v.vz[j]}, wi, wj, v.RS[e],
                   v.SRS[e], v.ME[e], Vec3{ft[0][e], ft[1][e], ft[2][e]}, v.cp, h);
  const ContactResponse& c = pc.c;
  store(ft[0], ft[1], ft[2], e, c.F_t);
  v.touch[e] = 1;
  Vec3 ti = pc.a_i * pc.tn, tj = pc.a_j * pc.tn;
  if constexpr (Model::kCouple) {
    double* const* ch = v.ph[1];
    const Vec3 M_r = Model::CoupleModel::moment(model.couple, pc.n, pc.c.k_n, pc.c.F_n,
                                                Vec3{ch[0][e], ch[1][e], ch[2][e]}, wi, wj, v.RS[e],
                                                v.cp.tangential_ratio, h);
    store(ch[0], ch[1], ch[2], e, M_r);
    ti += M_r;
    tj -= M_r;
  }
  store(v.rfx, v.rfy, v.rfz, e, c.force);
  store(v.rix, v.riy, v.riz, e, ti);
  store(v.rjx, v.rjy, v.rjz, e, tj);
  if (v.esig) {  // as the CPU pair loop (integrate/pair_loop.cpp, record_contact_load)
    v.esig[e] = pair_contact_stress(c.F_n, v.inv_pi_k, v.RS[e], pc.delta);
    v.eFn[e] = c.F_n;
    v.enx[e] = pc.n.x;
    v.eny[e] = pc.n.y;
    v.enz[e] = pc.n.z;
  }
}

template <class Model>
CD_HD inline void wall_item(const View& v, const Model& model, Index e) {
  const Index i = v.wp[e];
  const int k = v.ww[e];
  const WallDev& W = v.ctrl->walls[k];
  const BodyShape& body = v.shape[k];
  const BodyContact bc =
      body_contact(body, W.position, W.velocity, Vec3{v.x[i], v.y[i], v.z[i]}, v.radius[i]);
  const double dist = bc.dist;
  const double delta = v.radius[i] - dist;
  if (delta <= 0.0) {
    // Apart: no history, no force, no load.
    double* const cleared[] = {v.wftx, v.wfty, v.wftz, v.wfx, v.wfy, v.wfz,
                               v.wtx,  v.wty,  v.wtz,  v.wFn, v.wkn, v.wdelta};
    for (double* a : cleared) a[e] = 0.0;
    if (v.wsig) v.wsig[e] = v.wFel[e] = 0.0;
    return;
  }
  const double R_star = bc.R_star;
  const WallContact wcon =
      wall_contact(model.wall_law, bc.n, dist, delta, R_star, v.mass[i],
                   Vec3{v.vx[i], v.vy[i], v.vz[i]}, Vec3{v.wx[i], v.wy[i], v.wz[i]}, bc.velocity,
                   Vec3{v.wftx[e], v.wfty[e], v.wftz[e]}, body.friction, v.cp, v.ctrl->h);
  const ContactResponse& r = wcon.c;
  store(v.wftx, v.wfty, v.wftz, e, r.F_t);
  store(v.wfx, v.wfy, v.wfz, e, r.force);
  store(v.wtx, v.wty, v.wtz, e, wcon.torque);
  v.wFn[e] = wcon.F_n_wall;
  v.wkn[e] = r.k_n;
  v.wdelta[e] = delta;
  if (v.wsig) {  // as Simulation::wall_contact_load: the elastic force, r' = k R*
    v.wFel[e] = r.F_n;
    v.wsig[e] = contact_stress(r.F_n, v.load_factor * R_star, delta);
  }
}

/// Thread t's share of wall k's totals: entries t, t + kWallThreads, ... in order.
CD_HD inline WallSum wall_partial(const View& v, int k, int t) {
  WallSum s{0.0, 0.0, 0.0, 0.0, 0.0};
  const Index Mw = v.ctrl->Mw;
  for (Index e = static_cast<Index>(t); e < Mw; e += kWallThreads) {
    if (v.ww[e] != k) continue;
    s.Fn += v.wFn[e];
    s.fx -= v.wfx[e];
    s.fy -= v.wfy[e];
    s.fz -= v.wfz[e];
    s.k += v.wkn[e];
  }
  return s;
}

CD_HD inline void add_sum(WallSum& a, const WallSum& b) {
  a.Fn += b.Fn;
  a.fx += b.fx;
  a.fy += b.fy;
  a.fz += b.fz;
  a.k += b.k;
}

/// Stores body k's totals and sets its velocity for the next step (Walls::update_velocities).
CD_HD inline void wall_store_and_servo(const View& v, int k, const WallSum& sum) {
  WallDev* W = v.ctrl->walls;
  WallDev& s = W[k];
  s.normal_force = sum.Fn;
  s.fx = sum.fx;
  s.fy = sum.fy;
  s.fz = sum.fz;
  s.stiffness = sum.k;
  const WallCfgDev& c = v.wcfg[k];
  if (c.mode == 0) {
    s.velocity = 0.0;
  } else if (c.mode == 1) {
    s.velocity = c.velocity;
  } else {
    double area = 0.0;
    if (const int ch = v.shape[k].chamber; ch >= 0) {  // a chamber sample's platen or wall
      area = chamber_area(k == ch, v.shape[ch].part[0].radius + W[ch].position, W[4].position,
                          W[5].position, v.shape[ch].sector);
    } else if (k < kNumWalls) {  // a box wall: the box's cross-section (Walls::area)
      const int a1 = (wall_axis(k) + 1) % 3, a2 = (wall_axis(k) + 2) % 3;
      area = (W[2 * a1 + 1].position - W[2 * a1].position) *
             (W[2 * a2 + 1].position - W[2 * a2].position);
    } else {
      area = v.body_area[k] > 0.0 ? v.body_area[k]
                                  : v.shape[k].sector * body_own_area(v.shape[k], s.position);
    }
    const double load = body_load(v.shape[k], s.normal_force, Vec3{s.fx, s.fy, s.fz});
    s.velocity = servo_velocity(v.shape[k].outward_sign, load, area, s.stiffness, v.ctrl->h,
                                c.target_stress, c.servo_alpha, c.max_speed);
  }
}

// The gather's loops unrolled 4 times on the device, so that several entries' loads are in
// flight at once (the loop bodies are loads and adds). Measured on the H100, reference packing,
// Hertz: 4.1e8 particle-steps/s rolled (32 registers), 4.7e8 unrolled twice, 5.0e8 four times
// (40 registers). The order of the sums is unchanged.
#ifdef __CUDA_ARCH__
#define CD_GATHER_UNROLL _Pragma("unroll 4")
#else
#define CD_GATHER_UNROLL
#endif

/// Grain j's contact load over its own entries, its partner entries and its walls.
CD_HD inline void load_item(const View& v, Index j) {
  double S = 0.0, Fm = 0.0, nx = 0.0, ny = 0.0, nz = 0.0;
  for (Index e = v.off[j]; e < v.off[j + 1]; ++e) {
    if (!v.touch[e]) continue;
    take_contact_load(S, Fm, nx, ny, nz, v.esig[e], v.eFn[e], Vec3{v.enx[e], v.eny[e], v.enz[e]});
  }
  for (Index q = v.roff[j]; q < v.roff[j + 1]; ++q) {
    const Index e = v.rev[q];
    if (!v.touch[e]) continue;
    take_contact_load(S, Fm, nx, ny, nz, v.esig[e], v.eFn[e],
                      Vec3{-v.enx[e], -v.eny[e], -v.enz[e]});
  }
  for (Index e = v.woff[j]; e < v.woff[j + 1]; ++e) {
    if (v.wdelta[e] <= 0.0) continue;
    const int k = v.ww[e];
    int part = 0;
    const Vec3 n =
        body_surface(v.shape[k], v.ctrl->walls[k].position, Vec3{v.x[j], v.y[j], v.z[j]}, part).n;
    take_contact_load(S, Fm, nx, ny, nz, v.wsig[e], v.wFel[e], n);
  }
  v.LS[j] = S;
  v.LF[j] = Fm;
  v.LNX[j] = nx;
  v.LNY[j] = ny;
  v.LNZ[j] = nz;
}

CD_HD inline void gather_item(const View& v, Index j) {
  Vec3 F{}, T{};
  CD_GATHER_UNROLL
  for (Index e = v.off[j]; e < v.off[j + 1]; ++e) {
    if (!v.touch[e]) continue;
    F += Vec3{v.rfx[e], v.rfy[e], v.rfz[e]};
    T += Vec3{v.rix[e], v.riy[e], v.riz[e]};
  }
  CD_GATHER_UNROLL
  for (Index q = v.roff[j]; q < v.roff[j + 1]; ++q) {
    const Index e = v.rev[q];
    if (!v.touch[e]) continue;
    F -= Vec3{v.rfx[e], v.rfy[e], v.rfz[e]};
    T += Vec3{v.rjx[e], v.rjy[e], v.rjz[e]};
  }
  CD_GATHER_UNROLL
  for (Index e = v.woff[j]; e < v.woff[j + 1]; ++e) {
    F += Vec3{v.wfx[e], v.wfy[e], v.wfz[e]};
    T += Vec3{v.wtx[e], v.wty[e], v.wtz[e]};
  }
  if (v.has_gravity) F += v.mass[j] * v.gravity;  // after the contacts, as the CPU adds it
  if (v.LS) load_item(v, j);
  v.fux[j] = F.x;
  v.fuy[j] = F.y;
  v.fuz[j] = F.z;
  if (v.alpha > 0.0) {
    damp(v.alpha, Vec3{v.vx[j], v.vy[j], v.vz[j]}, Vec3{v.wx[j], v.wy[j], v.wz[j]}, F, T);
  }
  store(v.fx, v.fy, v.fz, j, F);
  store(v.tx, v.ty, v.tz, j, T);
  half_kick(v.ctrl->hh, v.cp.spin_scale, v.inv_mass[j], v.inv_inertia[j], F, T, v.vx[j], v.vy[j],
            v.vz[j], v.wx[j], v.wy[j], v.wz[j]);
}

/// The end of a step, by one thread after the gather: the clock as the host advances it, and
/// at a crushing step the time since the last check.
CD_HD inline void advance_clock(const View& v) {
  Control& c = *v.ctrl;
  c.time += c.h;
  ++c.steps;
  ++c.steps_done;
  if (v.crush_interval > 0 && c.steps % v.crush_interval == 0) {
    c.check_elapsed = c.time - c.last_check_time;
    c.last_check_time = c.time;
  }
}

/// Grain i's share of the inspection: its resultant force's magnitude, and the elastic F_n of
/// its own touching pairs (as Simulation::contacts() computes them) with their count.
template <class Model>
CD_HD inline InspectSum inspect_item(const View& v, const Model& model, Index i) {
  InspectSum s{std::sqrt(v.fux[i] * v.fux[i] + v.fuy[i] * v.fuy[i] + v.fuz[i] * v.fuz[i]), 0.0,
               0.0};
  for (Index e = v.off[i]; e < v.off[i + 1]; ++e) {
    if (!v.touch[e]) continue;
    const Index j = v.nb[e];
    const double dx = v.x[j] - v.x[i], dy = v.y[j] - v.y[i], dz = v.z[j] - v.z[i];
    const double delta = v.radius[i] + v.radius[j] - std::sqrt(dx * dx + dy * dy + dz * dz);
    s.F_n += model.pair_law(delta, v.RS[e], v.SRS[e]).F_n;
    s.pairs += 1.0;
  }
  return s;
}

CD_HD inline void add_inspect(InspectSum& a, const InspectSum& b) {
  a.resultant += b.resultant;
  a.F_n += b.F_n;
  a.pairs += b.pairs;
}

/// Grain j's stiffness time sqrt(m_j / sum k) for the automatic time step, k = (1 + k_t / k_n)
/// k_n of each touching pair and wall contact (infinite without one): the host's
/// stiffness_time() (integrate/time_step.cpp) term by term, its pair terms in increasing entry
/// order (own and partner entries merged) and then its wall entries, so the bits are the host's.
template <class Model>
CD_HD inline double stiffness_time_item(const View& v, const Model& model, Index j) {
  const double kt_ratio = 1.0 + v.cp.tangential_ratio;
  double ksum = 0.0;
  Index e = v.off[j];
  const Index e_end = v.off[j + 1];
  Index q = v.roff[j];
  const Index q_end = v.roff[j + 1];
  while (e < e_end || q < q_end) {
    const bool own = q == q_end || (e < e_end && e < v.rev[q]);
    const Index k = own ? e++ : v.rev[q++];
    const Index i = v.owner[k], n = v.nb[k];
    const double dx = v.x[n] - v.x[i], dy = v.y[n] - v.y[i], dz = v.z[n] - v.z[i];
    const double delta = v.radius[i] + v.radius[n] - std::sqrt(dx * dx + dy * dy + dz * dz);
    if (delta <= 0.0) continue;
    ksum += kt_ratio * model.pair_law(delta, v.RS[k], v.SRS[k]).k_n;
  }
  for (Index w = v.woff[j]; w < v.woff[j + 1]; ++w) {
    const int b = v.ww[w];
    int part = 0;
    const SurfacePoint s =
        body_surface(v.shape[b], v.ctrl->walls[b].position, Vec3{v.x[j], v.y[j], v.z[j]}, part);
    const double delta = v.radius[j] - s.dist;
    if (delta > 0.0) {
      const double R_star = surface_R_star(v.radius[j], s.kappa_1, s.kappa_2);
      ksum += kt_ratio * model.wall_law(delta, R_star, std::sqrt(R_star)).k_n;
    }
  }
  return ksum > 0.0 ? std::sqrt(v.mass[j] / ksum) : std::numeric_limits<double>::infinity();
}

/// Whether the step just finished is a crushing step.
CD_HD inline bool crushing_step(const View& v) {
  return v.crush_interval > 0 && v.ctrl->steps % v.crush_interval == 0;
}

/// The crushing check of grain i (fracture/crack_growth.hpp): its failure flag; true when it
/// fails.
CD_HD inline bool crushing_item(const View& v, Index i) {
  const GrainFailure f = crushing_check(v.radius[i], v.d_c, v.LS[i], v.sigma_lim[i], v.crack_growth,
                                        v.v0, v.n_charles, v.ctrl->check_elapsed, v.crack_a[i]);
  v.fail[i] = static_cast<std::uint8_t>(f);
  return f != GrainFailure::None;
}

}  // namespace crushdem::device
