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
//                 carrying the history by ids, and uploads again);
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

#include "crushdem/contact/contact_kernel.hpp"
#include "crushdem/contact/contact_stress.hpp"
#include "crushdem/fracture/crack_growth.hpp"
#include "crushdem/integrate/step_rules.hpp"
#include "crushdem/neighbor/neighbor_list.hpp"
#include "crushdem/walls/wall_geometry.hpp"

namespace crushdem::device {

using Index = std::uint32_t;

constexpr int kBlock = 256;           // threads per block of the per-grain kernels
constexpr int kContactBlock = 128;    // threads per block of the contact kernel
constexpr int kWallThreads = kBlock;  // threads per wall for the wall totals (a power of two)
constexpr int kInspectBlock = 256;    // grains per block of the inspection's first pass
constexpr int kBatchSteps = 100;      // steps per batch (one CUDA graph launch)

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
  WallDev walls[kNumWalls];
};

/// Everything a kernel touches, passed by value: fixed between uploads that do not reallocate
/// or change a parameter (a change makes a new view and, on the GPU, a new graph).
struct View {
  // Per grain, both ways.
  double *x, *y, *z, *vx, *vy, *vz, *wx, *wy, *wz, *fx, *fy, *fz, *tx, *ty, *tz;
  double *fux, *fuy, *fuz;  // resultant force before local damping (for output)
  // Per grain, uploaded only (they change with the layout).
  const double *radius, *mass, *inv_mass, *inv_inertia, *x0, *y0, *z0;
  // The half list, its reverse (entries where the grain is the partner) and per-entry R*,
  // sqrt(R*), m*.
  const Index *owner, *nb, *off, *roff, *rev;
  const double *RS, *SRS, *ME;
  // Per entry, both ways: tangential force and rolling moment on the owner (null without
  // rolling resistance), touching flag.
  double *ftx, *fty, *ftz;
  double *mrx, *mry, *mrz;
  std::uint8_t* touch;
  double *rfx, *rfy, *rfz, *rix, *riy, *riz, *rjx, *rjy, *rjz;  // reaction records per entry
  // Contact load (null unless tracked): per pair entry sigma_c, elastic F_n and the normal
  // i -> j; per wall entry sigma_c and elastic F_n; per grain the maxima.
  double *esig, *eFn, *enx, *eny, *enz, *wsig, *wFel;
  double *LS, *LF, *LNX, *LNY, *LNZ;
  double inv_pi_k, load_factor;  // 1 / (pi r'/R*) and r'/R*
  // Wall entries: grain, wall, CSR by grain; history and results, both ways.
  const Index *wp, *woff;
  const std::uint8_t* ww;
  double *wftx, *wfty, *wftz, *wfx, *wfy, *wfz, *wtx, *wty, *wtz, *wFn, *wkn, *wdelta;
  // Crushing (null unless on): strength (up), crack half-length (both ways), failure flags.
  const double* sigma_lim;
  double* crack_a;
  std::uint8_t* fail;
  double d_c, v0, n_charles;
  bool crack_growth;
  std::uint64_t crush_interval;  // 0: no crushing check
  InspectSum* inspect_partial;   // one per block of the inspection's first pass
  Control* ctrl;
  // Room in the buffers (grains, pair entries, wall entries): the kernels' grids cover these,
  // so the counts in the control block may change within them.
  unsigned grain_capacity, entry_capacity, wall_entry_capacity;
  double alpha, skin;
  WallCfgDev wcfg[kNumWalls];
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
  for (int k = 0; k < kNumWalls; ++k) {
    WallDev& s = c.walls[k];
    s.position += s.velocity * c.h;
    s.displacement += std::fabs(s.velocity * c.h);
    travel = travel < s.displacement ? s.displacement : travel;
  }
  if (rebuild_due(std::sqrt(m2), travel, v.skin)) c.halt = kRebuild;
}

template <class Law, bool Rolling>
CD_HD inline void pair_item(const View& v, const Law& law, Index e) {
  const Index i = v.owner[e], j = v.nb[e];
  const Vec3 xi{v.x[i], v.y[i], v.z[i]};
  const double ri = v.radius[i];
  const Vec3 dx{v.x[j] - xi.x, v.y[j] - xi.y, v.z[j] - xi.z};
  const double d2 = dot(dx, dx);
  const double rsum = ri + v.radius[j];
  if (d2 >= rsum * rsum) {
    if (v.touch[e]) {
      v.touch[e] = 0;
      v.ftx[e] = v.fty[e] = v.ftz[e] = 0.0;
      if constexpr (Rolling) v.mrx[e] = v.mry[e] = v.mrz[e] = 0.0;
    }
    return;
  }
  const Vec3 wi{v.wx[i], v.wy[i], v.wz[i]};
  const Vec3 wj{v.wx[j], v.wy[j], v.wz[j]};
  const double h = v.ctrl->h;
  const PairContact pc = pair_contact(
      law, dx, d2, ri, v.radius[j], Vec3{v.vx[i] - v.vx[j], v.vy[i] - v.vy[j], v.vz[i] - v.vz[j]},
      wi, wj, v.RS[e], v.SRS[e], v.ME[e], Vec3{v.ftx[e], v.fty[e], v.ftz[e]}, v.cp, h);
  const ContactResponse& c = pc.c;
  v.ftx[e] = c.F_t.x;
  v.fty[e] = c.F_t.y;
  v.ftz[e] = c.F_t.z;
  v.touch[e] = 1;
  Vec3 ti = pc.a_i * pc.tn, tj = pc.a_j * pc.tn;
  if constexpr (Rolling) {
    const Vec3 M_r = pair_rolling_moment(
        pc.n, pc.c.k_n, pc.c.F_n, Vec3{v.mrx[e], v.mry[e], v.mrz[e]}, wi, wj, v.RS[e], v.cp, h);
    v.mrx[e] = M_r.x;
    v.mry[e] = M_r.y;
    v.mrz[e] = M_r.z;
    ti += M_r;
    tj -= M_r;
  }
  v.rfx[e] = c.force.x;
  v.rfy[e] = c.force.y;
  v.rfz[e] = c.force.z;
  v.rix[e] = ti.x;
  v.riy[e] = ti.y;
  v.riz[e] = ti.z;
  v.rjx[e] = tj.x;
  v.rjy[e] = tj.y;
  v.rjz[e] = tj.z;
  if (v.esig) {  // as the CPU pair loop (integrate/pair_loop.cpp, record_contact_load)
    v.esig[e] = pair_contact_stress(c.F_n, v.inv_pi_k, v.RS[e], pc.delta);
    v.eFn[e] = c.F_n;
    v.enx[e] = pc.n.x;
    v.eny[e] = pc.n.y;
    v.enz[e] = pc.n.z;
  }
}

template <class Law>
CD_HD inline void wall_item(const View& v, const Law& law, Index e) {
  const Index i = v.wp[e];
  const int k = v.ww[e];
  const WallDev& W = v.ctrl->walls[k];
  const double dist = wall_gap(k, W.position, v.x[i], v.y[i], v.z[i]);
  const double delta = v.radius[i] - dist;
  if (delta <= 0.0) {
    v.wftx[e] = v.wfty[e] = v.wftz[e] = 0.0;
    v.wfx[e] = v.wfy[e] = v.wfz[e] = v.wtx[e] = v.wty[e] = v.wtz[e] = 0.0;
    v.wFn[e] = v.wkn[e] = v.wdelta[e] = 0.0;
    if (v.wsig) v.wsig[e] = v.wFel[e] = 0.0;
    return;
  }
  const WallContact wcon = wall_contact(
      law, wall_outward_normal(k), dist, delta, v.radius[i], v.mass[i],
      Vec3{v.vx[i], v.vy[i], v.vz[i]}, Vec3{v.wx[i], v.wy[i], v.wz[i]},
      wall_velocity_vector(k, W.velocity), Vec3{v.wftx[e], v.wfty[e], v.wftz[e]}, v.cp, v.ctrl->h);
  const ContactResponse& r = wcon.c;
  v.wftx[e] = r.F_t.x;
  v.wfty[e] = r.F_t.y;
  v.wftz[e] = r.F_t.z;
  v.wfx[e] = r.force.x;
  v.wfy[e] = r.force.y;
  v.wfz[e] = r.force.z;
  v.wtx[e] = wcon.torque.x;
  v.wty[e] = wcon.torque.y;
  v.wtz[e] = wcon.torque.z;
  v.wFn[e] = wcon.F_n_wall;
  v.wkn[e] = r.k_n;
  v.wdelta[e] = delta;
  if (v.wsig) {  // as Simulation::wall_contact_load: the elastic force, r' = k R
    v.wFel[e] = r.F_n;
    v.wsig[e] = contact_stress(r.F_n, v.load_factor * v.radius[i], delta);
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

/// Stores wall k's totals and sets its velocity for the next step (Walls::update_velocities).
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
    const int a1 = (wall_axis(k) + 1) % 3, a2 = (wall_axis(k) + 2) % 3;
    const double area = (W[2 * a1 + 1].position - W[2 * a1].position) *
                        (W[2 * a2 + 1].position - W[2 * a2].position);
    s.velocity = servo_wall_velocity(k, s.normal_force, area, s.stiffness, v.ctrl->h,
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
    take_contact_load(S, Fm, nx, ny, nz, v.wsig[e], v.wFel[e], wall_outward_normal(v.ww[e]));
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
  if (v.LS) load_item(v, j);
  v.fux[j] = F.x;
  v.fuy[j] = F.y;
  v.fuz[j] = F.z;
  if (v.alpha > 0.0) {
    damp(v.alpha, Vec3{v.vx[j], v.vy[j], v.vz[j]}, Vec3{v.wx[j], v.wy[j], v.wz[j]}, F, T);
  }
  v.fx[j] = F.x;
  v.fy[j] = F.y;
  v.fz[j] = F.z;
  v.tx[j] = T.x;
  v.ty[j] = T.y;
  v.tz[j] = T.z;
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
template <class Law>
CD_HD inline InspectSum inspect_item(const View& v, const Law& law, Index i) {
  InspectSum s{std::sqrt(v.fux[i] * v.fux[i] + v.fuy[i] * v.fuy[i] + v.fuz[i] * v.fuz[i]), 0.0,
               0.0};
  for (Index e = v.off[i]; e < v.off[i + 1]; ++e) {
    if (!v.touch[e]) continue;
    const Index j = v.nb[e];
    const double dx = v.x[j] - v.x[i], dy = v.y[j] - v.y[i], dz = v.z[j] - v.z[i];
    const double delta = v.radius[i] + v.radius[j] - std::sqrt(dx * dx + dy * dy + dz * dz);
    s.F_n += law(delta, v.RS[e], v.SRS[e]).F_n;
    s.pairs += 1.0;
  }
  return s;
}

CD_HD inline void add_inspect(InspectSum& a, const InspectSum& b) {
  a.resultant += b.resultant;
  a.F_n += b.F_n;
  a.pairs += b.pairs;
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
