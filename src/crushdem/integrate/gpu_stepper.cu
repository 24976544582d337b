// The CUDA time-stepper (see gpu_stepper.hpp). One step, as three kernels in one stream:
//
//   kick_drift    first half kick and drift per particle, largest squared displacement since
//                 the neighbour build (block maximum, then an integer atomicMax on the bits of a
//                 non-negative double: a maximum is exact, so the result does not depend on the
//                 order). The last block to finish (atomic ticket) moves the walls and applies
//                 the rebuild criterion (2 d > skin or d + wall travel > skin); when a rebuild is
//                 due it sets `halt` and every later kernel of the batch returns at once, so the
//                 host finds the state just after that drift;
//   contacts      one thread per neighbour entry (contact_response with the CPU loop's geometry,
//                 new history, touching flag and a reaction record: force on the owner, torques
//                 on owner and partner), then one thread per wall entry (the CPU's wall_forces);
//   gather        one thread per particle: own entries, then entries where it is the partner in
//                 increasing entry order (reverse CSR built on the host at upload), then its wall
//                 entries; local damping and the second half kick (gather_and_damp). Six extra
//                 blocks, one per wall, make the wall totals: each thread sums a fixed stride of
//                 the wall entries, then a fixed tree in shared memory; thread 0 stores the
//                 totals and sets the servo velocity (Walls::update_velocities for that wall).
//
// With contact-load tracking on (Simulation::track_contact_load, for crushing), the contact
// threads also keep each entry's contact stress F_n / (pi r' delta), elastic F_n and normal, and
// the gather takes each grain's maxima over its entries (own, partner, walls): the CPU's
// Simulation::contact_load(), which download() fills.
//
// No floating-point atomics anywhere: every sum has an order fixed by the lists, so runs repeat
// bit for bit. Batches of steps are launched as one CUDA graph; sizes live in device memory and
// buffers keep spare capacity so that the graph survives neighbour rebuilds.
//
// Built with -fmad=false (CMakeLists.txt), so each contact's arithmetic is the host's. The
// per-thread bodies are __host__ __device__ functions: Mode::HostEmulation runs them serially on
// the host in the same order, which gives the device's bits without a device.
#include <cuda_runtime.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "crushdem/contact/contact_kernel.hpp"
#include "crushdem/contact/contact_stress.hpp"
#include "crushdem/core/error.hpp"
#include "crushdem/integrate/gpu_stepper.hpp"
#include "crushdem/integrate/local_damping.hpp"
#include "crushdem/integrate/simulation.hpp"

namespace crushdem {
namespace {

constexpr int kBlock = 256;           // threads per block of the per-particle kernels
constexpr int kContactBlock = 128;    // threads per block of the contact kernel
constexpr int kWallThreads = kBlock;  // threads per wall for the wall totals (a power of two)
constexpr int kGraphSteps = 100;      // steps per CUDA graph launch
constexpr int kWalls = 6;

using Index = std::uint32_t;

void check_cuda(cudaError_t e, const char* what, int line) {
  if (e != cudaSuccess) {
    throw RuntimeFailure(std::string("CUDA error: ") + cudaGetErrorString(e) + " in " + what +
                         " (gpu_stepper.cu:" + std::to_string(line) + ")");
  }
}
#define CD_CUDA(x) check_cuda((x), #x, __LINE__)

struct WallDev {
  double position, velocity, normal_force, fx, fy, fz, stiffness, displacement;
};

struct WallCfgDev {
  int mode;  // 0 fixed, 1 velocity, 2 servo
  double velocity, target_stress, servo_alpha, max_speed;
};

// Device-resident control block: read by every kernel, copied to the host after each batch.
struct Control {
  int halt;                    // a neighbour rebuild is due: the rest of the batch does nothing
  int steps_done;              // full steps completed since the last upload
  unsigned long long m2_bits;  // bits of the largest squared displacement of this step
  unsigned N, M, Mw;           // particles, neighbour entries, wall entries
  unsigned blocks_done;        // kick_drift blocks finished in this step (last-block ticket)
  WallDev walls[kWalls];
};

// Everything a kernel touches, passed by value (fixed between uploads that do not reallocate).
struct View {
  double *x, *y, *z, *vx, *vy, *vz, *wx, *wy, *wz, *fx, *fy, *fz, *tx, *ty, *tz;
  double *fux, *fuy, *fuz;  // resultant force before local damping (for output)
  const double *radius, *mass, *inv_mass, *inv_inertia, *x0, *y0, *z0;
  const Index *owner, *nb, *off, *roff, *rev;
  const double *RS, *SRS, *ME;
  double *ftx, *fty, *ftz;
  double *mrx, *mry, *mrz;  // rolling moment on the owner (null without rolling resistance)
  std::uint8_t* touch;
  double *rfx, *rfy, *rfz, *rix, *riy, *riz, *rjx, *rjy, *rjz;  // reaction records per entry
  // Contact load (null unless tracked): per pair entry sigma_c, elastic F_n and the normal i -> j;
  // per wall entry sigma_c and elastic F_n; per grain the maxima (Simulation::ContactLoad).
  double *esig, *eFn, *enx, *eny, *enz, *wsig, *wFel;
  double *LS, *LF, *LNX, *LNY, *LNZ;
  double inv_pi_k, load_factor;  // 1 / (pi r'/R*) and r'/R*
  const Index *wp, *woff;
  const std::uint8_t* ww;
  double *wftx, *wfty, *wftz, *wfx, *wfy, *wfz, *wtx, *wty, *wtz, *wFn, *wkn, *wdelta;
  Control* ctrl;
  double h, hh, alpha, skin;
  WallCfgDev wcfg[kWalls];
  ContactParams cp;
};

struct WallSum {  // plain (no initialisers): it lives in shared memory
  double Fn, fx, fy, fz, k;
};

// --- per-thread bodies (shared by the kernels and the host emulation) -------------------------

CD_HD inline double kick_drift_item(const View& v, Index i) {
  const double s = v.cp.spin_scale;  // 0 holds the spins at zero (rotation blocked)
  const double a = v.hh * v.inv_mass[i], b = s * (v.hh * v.inv_inertia[i]);
  v.vx[i] += a * v.fx[i];
  v.vy[i] += a * v.fy[i];
  v.vz[i] += a * v.fz[i];
  v.wx[i] = s * v.wx[i] + b * v.tx[i];
  v.wy[i] = s * v.wy[i] + b * v.ty[i];
  v.wz[i] = s * v.wz[i] + b * v.tz[i];
  v.x[i] += v.h * v.vx[i];
  v.y[i] += v.h * v.vy[i];
  v.z[i] += v.h * v.vz[i];
  const double dx = v.x[i] - v.x0[i], dy = v.y[i] - v.y0[i], dz = v.z[i] - v.z0[i];
  return dx * dx + dy * dy + dz * dz;
}

// Walls::move, then the rebuild criterion of Simulation::step.
CD_HD inline void finish_drift(const View& v, double m2) {
  Control& c = *v.ctrl;
  double travel = 0.0;
  for (int k = 0; k < kWalls; ++k) {
    WallDev& s = c.walls[k];
    s.position += s.velocity * v.h;
    s.displacement += std::fabs(s.velocity * v.h);
    travel = travel < s.displacement ? s.displacement : travel;
  }
  const double d = std::sqrt(m2);
  if (rebuild_due(d, travel, v.skin)) c.halt = 1;
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
  const PairContact pc = pair_contact(
      law, dx, d2, ri, v.radius[j], Vec3{v.vx[i] - v.vx[j], v.vy[i] - v.vy[j], v.vz[i] - v.vz[j]},
      wi, wj, v.RS[e], v.SRS[e], v.ME[e], Vec3{v.ftx[e], v.fty[e], v.ftz[e]}, v.cp, v.h);
  const ContactResponse& c = pc.c;
  const double a_i = pc.a_i, a_j = pc.a_j;
  v.ftx[e] = c.F_t.x;
  v.fty[e] = c.F_t.y;
  v.ftz[e] = c.F_t.z;
  v.touch[e] = 1;
  const Vec3& tn = pc.tn;
  Vec3 ti = a_i * tn, tj = a_j * tn;
  if constexpr (Rolling) {
    const Vec3 M_r = pair_rolling_moment(
        pc.n, pc.c.k_n, pc.c.F_n, Vec3{v.mrx[e], v.mry[e], v.mrz[e]}, wi, wj, v.RS[e], v.cp, v.h);
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
  if (v.esig) {  // as the CPU pair loop (simulation.cpp, pair_column)
    v.esig[e] = pair_contact_stress(c.F_n, v.inv_pi_k, v.RS[e], pc.delta);
    v.eFn[e] = c.F_n;
    v.enx[e] = pc.n.x;
    v.eny[e] = pc.n.y;
    v.enz[e] = pc.n.z;
  }
}

// Walls::outward_normal on the device: wall k is on axis k / 2, the low one (k even) faces -axis.
CD_HD inline Vec3 wall_outward_normal(int k) {
  Vec3 n{};
  const double s = k % 2 == 0 ? -1.0 : 1.0;
  if (k / 2 == 0) n.x = s;
  if (k / 2 == 1) n.y = s;
  if (k / 2 == 2) n.z = s;
  return n;
}

template <class Law>
CD_HD inline void wall_item(const View& v, const Law& law, Index e) {
  const Index i = v.wp[e];
  const int k = v.ww[e];
  const int axis = k / 2;
  const bool low = k % 2 == 0;
  const WallDev& W = v.ctrl->walls[k];
  const double c[3] = {v.x[i], v.y[i], v.z[i]};
  const double dist = low ? c[axis] - W.position : W.position - c[axis];
  const double delta = v.radius[i] - dist;
  if (delta <= 0.0) {
    v.wftx[e] = v.wfty[e] = v.wftz[e] = 0.0;
    v.wfx[e] = v.wfy[e] = v.wfz[e] = v.wtx[e] = v.wty[e] = v.wtz[e] = 0.0;
    v.wFn[e] = v.wkn[e] = v.wdelta[e] = 0.0;
    if (v.wsig) v.wsig[e] = v.wFel[e] = 0.0;
    return;
  }
  const Vec3 n = wall_outward_normal(k);
  const WallContact wcon =
      wall_contact(law, n, dist, delta, v.radius[i], v.mass[i], Vec3{v.vx[i], v.vy[i], v.vz[i]},
                   Vec3{v.wx[i], v.wy[i], v.wz[i]}, W.velocity * n * (low ? -1.0 : 1.0),
                   Vec3{v.wftx[e], v.wfty[e], v.wftz[e]}, v.cp, v.h);
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
  if (v.wsig) {  // Simulation::evaluate_forces: the elastic force, r' = k R
    v.wFel[e] = r.F_n;
    v.wsig[e] = contact_stress(r.F_n, v.load_factor * v.radius[i], delta);
  }
}

// Thread t's share of wall k's totals: entries t, t + kWallThreads, ... in order.
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

// Stores wall k's totals and sets its velocity for the next step (Walls::update_velocities).
CD_HD inline void wall_store_and_servo(const View& v, int k, const WallSum& sum) {
  WallDev* W = v.ctrl->walls;
  WallDev& s = W[k];
  s.normal_force = sum.Fn;
  s.fx = sum.fx;
  s.fy = sum.fy;
  s.fz = sum.fz;
  s.stiffness = sum.k;
  const WallCfgDev& c = v.wcfg[k];
  const double out = k % 2 == 0 ? -1.0 : 1.0;
  if (c.mode == 0) {
    s.velocity = 0.0;
  } else if (c.mode == 1) {
    s.velocity = c.velocity;
  } else {
    const int a = k / 2, a1 = (a + 1) % 3, a2 = (a + 2) % 3;
    const double area = (W[2 * a1 + 1].position - W[2 * a1].position) *
                        (W[2 * a2 + 1].position - W[2 * a2].position);
    const double error = s.normal_force / area - c.target_stress;
    double v_out;
    if (s.stiffness > 0.0 && v.h > 0.0) {
      v_out = c.servo_alpha * area / (s.stiffness * v.h) * error;
    } else {
      v_out = error > 0.0 ? c.max_speed : -c.max_speed;
    }
    v_out = v_out < -c.max_speed ? -c.max_speed : (c.max_speed < v_out ? c.max_speed : v_out);
    s.velocity = out * v_out;
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

// Grain j's contact load: the largest sigma_c, and the largest elastic F_n with its normal
// (pointing from j towards the contact), over its own entries, its partner entries and its
// walls. Maxima, so the result does not depend on the order (ties keep the first).
CD_HD inline void load_item(const View& v, Index j) {
  double S = 0.0, Fm = 0.0;
  Vec3 n{};
  for (Index e = v.off[j]; e < v.off[j + 1]; ++e) {
    if (!v.touch[e]) continue;
    if (v.esig[e] > S) S = v.esig[e];
    if (v.eFn[e] > Fm) {
      Fm = v.eFn[e];
      n = Vec3{v.enx[e], v.eny[e], v.enz[e]};
    }
  }
  for (Index q = v.roff[j]; q < v.roff[j + 1]; ++q) {
    const Index e = v.rev[q];
    if (!v.touch[e]) continue;
    if (v.esig[e] > S) S = v.esig[e];
    if (v.eFn[e] > Fm) {
      Fm = v.eFn[e];
      n = Vec3{-v.enx[e], -v.eny[e], -v.enz[e]};
    }
  }
  for (Index e = v.woff[j]; e < v.woff[j + 1]; ++e) {
    if (v.wdelta[e] <= 0.0) continue;
    if (v.wsig[e] > S) S = v.wsig[e];
    if (v.wFel[e] > Fm) {
      Fm = v.wFel[e];
      n = wall_outward_normal(v.ww[e]);
    }
  }
  v.LS[j] = S;
  v.LF[j] = Fm;
  v.LNX[j] = n.x;
  v.LNY[j] = n.y;
  v.LNZ[j] = n.z;
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
    F = {local_damping(F.x, v.vx[j], v.alpha), local_damping(F.y, v.vy[j], v.alpha),
         local_damping(F.z, v.vz[j], v.alpha)};
    T = {local_damping(T.x, v.wx[j], v.alpha), local_damping(T.y, v.wy[j], v.alpha),
         local_damping(T.z, v.wz[j], v.alpha)};
  }
  v.fx[j] = F.x;
  v.fy[j] = F.y;
  v.fz[j] = F.z;
  v.tx[j] = T.x;
  v.ty[j] = T.y;
  v.tz[j] = T.z;
  const double s = v.cp.spin_scale;
  const double a = v.hh * v.inv_mass[j], b = s * (v.hh * v.inv_inertia[j]);
  v.vx[j] += a * F.x;
  v.vy[j] += a * F.y;
  v.vz[j] += a * F.z;
  v.wx[j] = s * v.wx[j] + b * T.x;
  v.wy[j] = s * v.wy[j] + b * T.y;
  v.wz[j] = s * v.wz[j] + b * T.z;
}

// --- kernels -----------------------------------------------------------------------------------

__global__ void k_kick_drift(View v) {
  __shared__ double sm[kBlock];
  Control* c = v.ctrl;
  // The same for every thread: only the last block writes it, after all blocks have read it.
  if (c->halt) return;
  const Index i = blockIdx.x * blockDim.x + threadIdx.x;
  sm[threadIdx.x] = i < c->N ? kick_drift_item(v, i) : 0.0;
  __syncthreads();
  for (int s = kBlock / 2; s > 0; s >>= 1) {
    if (static_cast<int>(threadIdx.x) < s)
      sm[threadIdx.x] = fmax(sm[threadIdx.x], sm[threadIdx.x + s]);
    __syncthreads();
  }
  if (threadIdx.x == 0) {
    atomicMax(&c->m2_bits, static_cast<unsigned long long>(__double_as_longlong(sm[0])));
    __threadfence();
    if (atomicAdd(&c->blocks_done, 1u) == gridDim.x - 1) {
      // The last block: every block's maximum is in m2_bits.
      const unsigned long long m2 = atomicExch(&c->m2_bits, 0ull);
      c->blocks_done = 0;
      finish_drift(v, __longlong_as_double(static_cast<long long>(m2)));
    }
  }
}

template <class Law, bool Rolling>
__global__ void k_contacts(View v, Law pair_law, Law wall_law) {
  if (v.ctrl->halt) return;
  const Index t = blockIdx.x * blockDim.x + threadIdx.x;
  const Index M = v.ctrl->M;
  if (t < M) {
    pair_item<Law, Rolling>(v, pair_law, t);
  } else if (t - M < v.ctrl->Mw) {
    wall_item(v, wall_law, t - M);
  }
}

// Blocks below particle_blocks gather; the next kWalls blocks make the wall totals (they read
// only the wall entries and write only the walls, which the gather does not read).
__global__ void k_gather(View v, unsigned particle_blocks) {
  __shared__ WallSum sm[kWallThreads];
  if (v.ctrl->halt) return;
  if (blockIdx.x >= particle_blocks) {
    const int k = static_cast<int>(blockIdx.x - particle_blocks), t = threadIdx.x;
    sm[t] = wall_partial(v, k, t);
    __syncthreads();
    for (int s = kWallThreads / 2; s > 0; s >>= 1) {
      if (t < s) add_sum(sm[t], sm[t + s]);
      __syncthreads();
    }
    if (t == 0) wall_store_and_servo(v, k, sm[0]);
    return;
  }
  const Index j = blockIdx.x * blockDim.x + threadIdx.x;
  if (j < v.ctrl->N) gather_item(v, j);
  if (j == 0) ++v.ctrl->steps_done;
}

// --- memory ------------------------------------------------------------------------------------

template <class T>
struct Buffer {
  T* p = nullptr;
  std::size_t cap = 0;
};

int grid(std::size_t n, int block = kBlock) {
  return static_cast<int>((n + static_cast<std::size_t>(block) - 1) /
                          static_cast<std::size_t>(block));
}

}  // namespace

struct GpuStepper::Impl {
  Simulation& sim;
  bool emulate;
  double h = 0.0;
  bool rough = false;
  bool rolling = false;
  HertzLaw hertz;
  RoughHertzLaw rough_pp, rough_pw;  // their power tables point at device copies
  Buffer<double> tables[2];          // one block per law: pow_b's nodes, then pow_c's

  Buffer<double> x, y, z, vx, vy, vz, wx, wy, wz, fx, fy, fz, tx, ty, tz, fux, fuy, fuz;
  Buffer<double> radius, mass, inv_mass, inv_inertia, x0, y0, z0;
  Buffer<Index> owner, nb, off, roff, rev, wp, woff;
  Buffer<std::uint8_t> touch, ww;
  Buffer<double> RS, SRS, ME, ftx, fty, ftz, rfx, rfy, rfz, rix, riy, riz, rjx, rjy, rjz;
  Buffer<double> mrx, mry, mrz;  // rolling history (allocated with rolling resistance only)
  Buffer<double> wftx, wfty, wftz, wfx, wfy, wfz, wtx, wty, wtz, wFn, wkn, wdelta;
  // Contact load (allocated when the Simulation tracks it).
  Buffer<double> esig, eFn, enx, eny, enz, wsig, wFel, LS, LF, LNX, LNY, LNZ;
  bool track_load = false;
  Buffer<Control> ctrl;
  Control* host_ctrl = nullptr;  // pinned mirror (device) or the control block itself (emulation)

  std::size_t N = 0, M = 0, Mw = 0;
  View v{};
  bool reallocated = false;
  int seen_steps = 0;

  cudaStream_t stream = nullptr;
  cudaGraphExec_t graph = nullptr;
  bool graph_stale = true;

  Impl(Simulation& s, Mode mode) : sim(s), emulate(mode == Mode::HostEmulation) {
    if (!emulate) {
      if (!GpuStepper::available()) throw RuntimeFailure("GpuStepper: no CUDA device");
      CD_CUDA(cudaStreamCreateWithFlags(&stream, cudaStreamNonBlocking));
      CD_CUDA(cudaMallocHost(reinterpret_cast<void**>(&host_ctrl), sizeof(Control)));
    }
    // As at the start of Simulation::step: the step, then forces and lists if not current.
    h = sim.dt();
    if (!sim.forces_valid_ || !sim.nl_valid_) sim.compute_forces();
    const ContactParams& cp = sim.cp_;
    rough = sim.cfg_.contact.law == NormalLaw::Rough;
    rolling = sim.rolling();
    track_load = sim.load_factor_ > 0.0;
    hertz = HertzLaw{cp.E_star};
    rough_pp = RoughHertzLaw{cp.E_star, cp.rough_pp};
    rough_pw = RoughHertzLaw{cp.E_star, cp.rough_pw};
    if (!emulate && rough) {
      // Each law's two tables are one block on the host (power_table_pair(): the kernel picks
      // pow_c by an offset from pow_b's nodes) and are copied as one.
      RoughHertzParams* laws[2] = {&rough_pp.rough, &rough_pw.rough};
      for (int k = 0; k < 2; ++k) {
        RoughHertzParams& r = *laws[k];
        const std::size_t one = 2 * static_cast<std::size_t>(r.pow_b.n + 1);
        put(tables[k], r.pow_b.nodes, 2 * one);
        r.pow_b.nodes = tables[k].p;
        r.pow_c.nodes = tables[k].p + one;
      }
    }
    upload();
  }

  ~Impl() {
    if (graph) cudaGraphExecDestroy(graph);
    for (auto& b : tables) release(b);
    for (auto* b : {&x,   &y,   &z,   &vx,  &vy,  &vz,     &wx,   &wy,       &wz,          &fx,
                    &fy,  &fz,  &tx,  &ty,  &tz,  &radius, &mass, &inv_mass, &inv_inertia, &x0,
                    &y0,  &z0,  &RS,  &SRS, &ME,  &ftx,    &fty,  &ftz,      &rfx,         &rfy,
                    &rfz, &rix, &riy, &riz, &rjx, &rjy,    &rjz,  &wftx,     &wfty,        &wftz,
                    &wfx, &wfy, &wfz, &wtx, &wty, &wtz,    &wFn,  &wkn,      &wdelta}) {
      release(*b);
    }
    for (auto* b : {&mrx, &mry, &mrz}) release(*b);
    for (auto* b : {&esig, &eFn, &enx, &eny, &enz, &wsig, &wFel, &LS, &LF, &LNX, &LNY, &LNZ}) {
      release(*b);
    }
    for (auto* b : {&fux, &fuy, &fuz}) release(*b);
    for (auto* b : {&owner, &nb, &off, &roff, &rev, &wp, &woff}) release(*b);
    release(touch);
    release(ww);
    release(ctrl);
    if (!emulate) {
      if (host_ctrl) cudaFreeHost(host_ctrl);
      if (stream) cudaStreamDestroy(stream);
    }
  }

  // --- buffers ---------------------------------------------------------------------------------

  template <class T>
  void release(Buffer<T>& b) {
    if (!b.p) return;
    if (emulate) {
      std::free(b.p);
    } else {
      cudaFree(b.p);
    }
    b.p = nullptr;
    b.cap = 0;
  }

  // Makes room for n elements, with spare capacity so that rebuilds rarely reallocate.
  template <class T>
  void reserve(Buffer<T>& b, std::size_t n) {
    if (b.p && n <= b.cap) return;
    release(b);
    const std::size_t cap = std::max<std::size_t>(n + n / 4, 64);
    if (emulate) {
      b.p = static_cast<T*>(std::malloc(cap * sizeof(T)));
      if (!b.p) throw RuntimeFailure("GpuStepper: out of host memory");
    } else {
      CD_CUDA(cudaMalloc(reinterpret_cast<void**>(&b.p), cap * sizeof(T)));
    }
    b.cap = cap;
    reallocated = true;
  }

  template <class T>
  void put(Buffer<T>& b, const T* src, std::size_t n) {
    reserve(b, n);
    if (n == 0) return;
    if (emulate) {
      std::memcpy(b.p, src, n * sizeof(T));
    } else {
      CD_CUDA(cudaMemcpy(b.p, src, n * sizeof(T), cudaMemcpyHostToDevice));
    }
  }
  template <class T>
  void put(Buffer<T>& b, const std::vector<T>& src) {
    put(b, src.data(), src.size());
  }

  template <class T>
  void get(const Buffer<T>& b, std::vector<T>& dst, std::size_t n) {
    dst.resize(n);
    if (n == 0) return;
    if (emulate) {
      std::memcpy(dst.data(), b.p, n * sizeof(T));
    } else {
      CD_CUDA(cudaMemcpy(dst.data(), b.p, n * sizeof(T), cudaMemcpyDeviceToHost));
    }
  }

  // --- state transfer --------------------------------------------------------------------------

  void upload() {
    const ParticleStore& p = sim.p_;
    const NeighborList& nl = sim.nl_;
    const WallContacts& wc = sim.wc_;
    N = p.size();
    M = nl.neighbors.size();
    Mw = wc.size();

    put(x, p.x);
    put(y, p.y);
    put(z, p.z);
    put(vx, p.vx);
    put(vy, p.vy);
    put(vz, p.vz);
    put(wx, p.wx);
    put(wy, p.wy);
    put(wz, p.wz);
    put(fx, p.fx);
    put(fy, p.fy);
    put(fz, p.fz);
    put(tx, p.tx);
    put(ty, p.ty);
    put(tz, p.tz);
    put(fux, sim.fu_x_);
    put(fuy, sim.fu_y_);
    put(fuz, sim.fu_z_);
    put(radius, p.radius);
    put(mass, p.mass);
    put(inv_mass, p.inv_mass);
    put(inv_inertia, p.inv_inertia);
    put(x0, nl.x_ref());
    put(y0, nl.y_ref());
    put(z0, nl.z_ref());

    // Half list, and its reverse: the entries where particle j is the partner, increasing.
    std::vector<Index> offsets = nl.offsets;
    offsets.resize(N + 1, static_cast<Index>(M));
    std::vector<Index> r_off(N + 1, 0), r_ent(M);
    for (std::size_t e = 0; e < M; ++e) ++r_off[nl.neighbors[e] + 1];
    for (std::size_t j = 0; j < N; ++j) r_off[j + 1] += r_off[j];
    {
      std::vector<Index> fill(r_off.begin(), r_off.end() - 1);
      for (std::size_t e = 0; e < M; ++e) r_ent[fill[nl.neighbors[e]]++] = static_cast<Index>(e);
    }
    put(owner, nl.owner);
    put(nb, nl.neighbors);
    put(off, offsets);
    put(roff, r_off);
    put(rev, r_ent);
    {
      // Per entry R*, sqrt(R*) and m* (the CPU loop computes the same expressions in its lanes).
      std::vector<double> rs(M), srs(M), me(M);
      for (std::size_t e = 0; e < M; ++e) {
        const std::size_t i = nl.owner[e], j = nl.neighbors[e];
        rs[e] = pair_R_star(p.radius[i], p.radius[j]);
        srs[e] = std::sqrt(rs[e]);
        me[e] = pair_m_eff(p.inv_mass[i], p.inv_mass[j]);
      }
      put(RS, rs);
      put(SRS, srs);
      put(ME, me);
    }
    put(ftx, sim.ft_x_);
    put(fty, sim.ft_y_);
    put(ftz, sim.ft_z_);
    if (rolling) {
      put(mrx, sim.mr_x_);
      put(mry, sim.mr_y_);
      put(mrz, sim.mr_z_);
    }
    put(touch, sim.touching_);
    for (auto* b : {&rfx, &rfy, &rfz, &rix, &riy, &riz, &rjx, &rjy, &rjz}) reserve(*b, M);

    std::vector<Index> w_off = sim.wall_offsets_;
    w_off.resize(N + 1, static_cast<Index>(Mw));
    put(wp, wc.particle);
    put(ww, wc.wall);
    put(woff, w_off);
    put(wftx, wc.ft_x);
    put(wfty, wc.ft_y);
    put(wftz, wc.ft_z);
    for (auto* b : {&wfx, &wfy, &wfz, &wtx, &wty, &wtz, &wFn, &wkn, &wdelta}) reserve(*b, Mw);
    if (track_load) {
      for (auto* b : {&esig, &eFn, &enx, &eny, &enz}) reserve(*b, M);
      for (auto* b : {&wsig, &wFel}) reserve(*b, Mw);
      // The host's current load (what download() returns before any step).
      const Simulation::ContactLoad& L = sim.load_;
      if (L.sigma.size() == N && L.F_n_max.size() == N && L.nx.size() == N) {
        put(LS, L.sigma);
        put(LF, L.F_n_max);
        put(LNX, L.nx);
        put(LNY, L.ny);
        put(LNZ, L.nz);
      } else {
        for (auto* b : {&LS, &LF, &LNX, &LNY, &LNZ}) reserve(*b, N);
      }
    }

    Control c{};
    c.N = static_cast<unsigned>(N);
    c.M = static_cast<unsigned>(M);
    c.Mw = static_cast<unsigned>(Mw);
    for (int k = 0; k < kWalls; ++k) {
      const WallState& s = sim.walls_.state(k);
      c.walls[k] = {s.position, s.velocity, s.normal_force, s.force.x,
                    s.force.y,  s.force.z,  s.stiffness,    s.displacement_since_build};
    }
    put(ctrl, &c, 1);
    seen_steps = 0;

    View u{};
    u.x = x.p;
    u.y = y.p;
    u.z = z.p;
    u.vx = vx.p;
    u.vy = vy.p;
    u.vz = vz.p;
    u.wx = wx.p;
    u.wy = wy.p;
    u.wz = wz.p;
    u.fx = fx.p;
    u.fux = fux.p;
    u.fuy = fuy.p;
    u.fuz = fuz.p;
    u.fy = fy.p;
    u.fz = fz.p;
    u.tx = tx.p;
    u.ty = ty.p;
    u.tz = tz.p;
    u.radius = radius.p;
    u.mass = mass.p;
    u.inv_mass = inv_mass.p;
    u.inv_inertia = inv_inertia.p;
    u.x0 = x0.p;
    u.y0 = y0.p;
    u.z0 = z0.p;
    u.owner = owner.p;
    u.nb = nb.p;
    u.off = off.p;
    u.roff = roff.p;
    u.rev = rev.p;
    u.RS = RS.p;
    u.SRS = SRS.p;
    u.ME = ME.p;
    u.ftx = ftx.p;
    u.fty = fty.p;
    u.ftz = ftz.p;
    u.mrx = rolling ? mrx.p : nullptr;
    u.mry = rolling ? mry.p : nullptr;
    u.mrz = rolling ? mrz.p : nullptr;
    u.touch = touch.p;
    u.rfx = rfx.p;
    u.rfy = rfy.p;
    u.rfz = rfz.p;
    u.rix = rix.p;
    u.riy = riy.p;
    u.riz = riz.p;
    u.rjx = rjx.p;
    u.rjy = rjy.p;
    u.rjz = rjz.p;
    u.wp = wp.p;
    u.woff = woff.p;
    u.ww = ww.p;
    u.wftx = wftx.p;
    u.wfty = wfty.p;
    u.wftz = wftz.p;
    u.wfx = wfx.p;
    u.wfy = wfy.p;
    u.wfz = wfz.p;
    u.wtx = wtx.p;
    u.wty = wty.p;
    u.wtz = wtz.p;
    u.wFn = wFn.p;
    u.wkn = wkn.p;
    u.wdelta = wdelta.p;
    if (track_load) {
      u.esig = esig.p;
      u.eFn = eFn.p;
      u.enx = enx.p;
      u.eny = eny.p;
      u.enz = enz.p;
      u.wsig = wsig.p;
      u.wFel = wFel.p;
      u.LS = LS.p;
      u.LF = LF.p;
      u.LNX = LNX.p;
      u.LNY = LNY.p;
      u.LNZ = LNZ.p;
      u.load_factor = sim.load_factor_;
      u.inv_pi_k = 1.0 / (kPi * sim.load_factor_);
    }
    u.ctrl = ctrl.p;
    u.h = h;
    u.hh = 0.5 * h;
    u.alpha = sim.cfg_.damping.local_alpha;
    u.skin = sim.skin_;
    for (int k = 0; k < kWalls; ++k) {
      const WallConfig& wcfg = sim.walls_.config(k);
      u.wcfg[k].mode = wcfg.mode == WallMode::Fixed ? 0 : (wcfg.mode == WallMode::Velocity ? 1 : 2);
      u.wcfg[k].velocity = wcfg.velocity;
      u.wcfg[k].target_stress = wcfg.target_stress;
      u.wcfg[k].servo_alpha = wcfg.servo_alpha;
      u.wcfg[k].max_speed = wcfg.max_speed;
    }
    u.cp = sim.cp_;
    v = u;
    if (reallocated) {
      graph_stale = true;
      reallocated = false;
    }
  }

  void read_control() {
    if (emulate) {
      if (host_ctrl != ctrl.p) host_ctrl = ctrl.p;
      return;
    }
    CD_CUDA(cudaMemcpyAsync(host_ctrl, ctrl.p, sizeof(Control), cudaMemcpyDeviceToHost, stream));
    CD_CUDA(cudaStreamSynchronize(stream));
  }

  void download() {
    read_control();
    ParticleStore& p = sim.p_;
    get(x, p.x, N);
    get(y, p.y, N);
    get(z, p.z, N);
    get(vx, p.vx, N);
    get(vy, p.vy, N);
    get(vz, p.vz, N);
    get(wx, p.wx, N);
    get(wy, p.wy, N);
    get(wz, p.wz, N);
    get(fx, p.fx, N);
    get(fy, p.fy, N);
    get(fz, p.fz, N);
    get(tx, p.tx, N);
    get(ty, p.ty, N);
    get(tz, p.tz, N);
    get(fux, sim.fu_x_, N);
    get(fuy, sim.fu_y_, N);
    get(fuz, sim.fu_z_, N);
    get(ftx, sim.ft_x_, M);
    get(fty, sim.ft_y_, M);
    get(ftz, sim.ft_z_, M);
    if (rolling) {
      get(mrx, sim.mr_x_, M);
      get(mry, sim.mr_y_, M);
      get(mrz, sim.mr_z_, M);
    }
    get(touch, sim.touching_, M);
    WallContacts& wc = sim.wc_;
    get(wftx, wc.ft_x, Mw);
    get(wfty, wc.ft_y, Mw);
    get(wftz, wc.ft_z, Mw);
    get(wfx, wc.fx, Mw);
    get(wfy, wc.fy, Mw);
    get(wfz, wc.fz, Mw);
    get(wtx, wc.tx, Mw);
    get(wty, wc.ty, Mw);
    get(wtz, wc.tz, Mw);
    get(wFn, wc.F_n, Mw);
    get(wkn, wc.k_n, Mw);
    get(wdelta, wc.delta, Mw);
    if (track_load) {
      Simulation::ContactLoad& L = sim.load_;
      get(LS, L.sigma, N);
      get(LF, L.F_n_max, N);
      get(LNX, L.nx, N);
      get(LNY, L.ny, N);
      get(LNZ, L.nz, N);
    }
    for (int k = 0; k < kWalls; ++k) {
      const WallDev& d = host_ctrl->walls[k];
      WallState& s = sim.walls_.state(k);
      s.position = d.position;
      s.velocity = d.velocity;
      s.normal_force = d.normal_force;
      s.force = {d.fx, d.fy, d.fz};
      s.stiffness = d.stiffness;
      s.displacement_since_build = d.displacement;
    }
    sim.forces_valid_ = true;
    sim.nl_valid_ = true;
  }

  // --- launching -------------------------------------------------------------------------------

  void launch_forces() {
    if (emulate) {
      emulate_forces();
      return;
    }
    const int gc = grid(RS.cap + wp.cap, kContactBlock), gp = grid(x.cap);
    if (rough && rolling) {
      k_contacts<RoughHertzLaw, true><<<gc, kContactBlock, 0, stream>>>(v, rough_pp, rough_pw);
    } else if (rough) {
      k_contacts<RoughHertzLaw, false><<<gc, kContactBlock, 0, stream>>>(v, rough_pp, rough_pw);
    } else if (rolling) {
      k_contacts<HertzLaw, true><<<gc, kContactBlock, 0, stream>>>(v, hertz, hertz);
    } else {
      k_contacts<HertzLaw, false><<<gc, kContactBlock, 0, stream>>>(v, hertz, hertz);
    }
    k_gather<<<gp + kWalls, kBlock, 0, stream>>>(v, static_cast<unsigned>(gp));
  }

  void launch_step() {
    if (emulate) {
      emulate_kick_drift();
      emulate_forces();
      return;
    }
    k_kick_drift<<<grid(x.cap), kBlock, 0, stream>>>(v);
    launch_forces();
  }

  void capture_graph() {
    if (graph) {
      CD_CUDA(cudaGraphExecDestroy(graph));
      graph = nullptr;
    }
    cudaGraph_t g = nullptr;
    CD_CUDA(cudaStreamBeginCapture(stream, cudaStreamCaptureModeThreadLocal));
    for (int s = 0; s < kGraphSteps; ++s) launch_step();
    CD_CUDA(cudaStreamEndCapture(stream, &g));
    const cudaError_t e = cudaGraphInstantiate(&graph, g, 0);
    cudaGraphDestroy(g);
    CD_CUDA(e);
    graph_stale = false;
  }

  // The host emulation: the kernels' bodies in the kernels' order of summation.
  void emulate_kick_drift() {
    Control& c = *v.ctrl;
    if (c.halt) return;
    double m2 = 0.0;
    for (Index i = 0; i < c.N; ++i) m2 = std::max(m2, kick_drift_item(v, i));
    finish_drift(v, m2);
  }

  void emulate_forces() {
    Control& c = *v.ctrl;
    if (c.halt) return;
    for (Index e = 0; e < c.M; ++e) {
      if (rough) {
        rolling ? pair_item<RoughHertzLaw, true>(v, rough_pp, e)
                : pair_item<RoughHertzLaw, false>(v, rough_pp, e);
      } else {
        rolling ? pair_item<HertzLaw, true>(v, hertz, e) : pair_item<HertzLaw, false>(v, hertz, e);
      }
    }
    for (Index e = 0; e < c.Mw; ++e) {
      if (rough) {
        wall_item(v, rough_pw, e);
      } else {
        wall_item(v, hertz, e);
      }
    }
    std::vector<WallSum> part(kWallThreads);
    for (int k = 0; k < kWalls; ++k) {
      for (int t = 0; t < kWallThreads; ++t)
        part[static_cast<std::size_t>(t)] = wall_partial(v, k, t);
      for (int s = kWallThreads / 2; s > 0; s >>= 1) {
        for (int t = 0; t < s; ++t) {
          add_sum(part[static_cast<std::size_t>(t)], part[static_cast<std::size_t>(t + s)]);
        }
      }
      wall_store_and_servo(v, k, part[0]);
    }
    for (Index j = 0; j < c.N; ++j) gather_item(v, j);
    ++c.steps_done;
  }

  void advance(std::uint64_t steps) {
    for (std::uint64_t s = 0; s < steps; ++s) {
      sim.time_ += h;
      ++sim.steps_;
    }
  }

  void step(std::uint64_t n) {
    std::uint64_t left = n;
    while (left > 0) {
      const std::uint64_t batch = std::min<std::uint64_t>(left, kGraphSteps);
      if (!emulate && batch == static_cast<std::uint64_t>(kGraphSteps)) {
        if (graph_stale) capture_graph();
        CD_CUDA(cudaGraphLaunch(graph, stream));
      } else {
        for (std::uint64_t s = 0; s < batch; ++s) launch_step();
      }
      if (!emulate) CD_CUDA(cudaGetLastError());
      read_control();
      const int done = host_ctrl->steps_done - seen_steps;
      seen_steps = host_ctrl->steps_done;
      advance(static_cast<std::uint64_t>(done));
      left -= static_cast<std::uint64_t>(done);
      if (host_ctrl->halt) {
        // The next step stopped after its drift: rebuild the list on the host (history carried
        // by ids), upload, and finish that step's forces and second half kick here.
        download();
        sim.rebuild_neighbors();
        upload();
        launch_forces();
        if (!emulate) CD_CUDA(cudaGetLastError());
        seen_steps = 1;
        advance(1);
        --left;
      } else if (static_cast<std::uint64_t>(done) != batch) {
        throw RuntimeFailure("GpuStepper: the device completed " + std::to_string(done) + " of " +
                             std::to_string(batch) + " steps");
      }
    }
    if (!emulate) CD_CUDA(cudaStreamSynchronize(stream));
  }
};

GpuStepper::GpuStepper(Simulation& sim, Mode mode) : impl_(std::make_unique<Impl>(sim, mode)) {}

GpuStepper::~GpuStepper() = default;

void GpuStepper::step(std::uint64_t n) {
  impl_->step(n);
}

void GpuStepper::download() {
  impl_->download();
}

bool GpuStepper::available() {
  int n = 0;
  if (cudaGetDeviceCount(&n) != cudaSuccess) {
    cudaGetLastError();  // clear the sticky "no device" error
    return false;
  }
  return n > 0;
}

}  // namespace crushdem
