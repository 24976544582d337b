#include "crushdem/integrate/integrator.hpp"

#include <cstddef>
#include <cstdint>
#include <limits>
#include <type_traits>

#include "crushdem/core/deterministic.hpp"
#include "crushdem/integrate/step_rules.hpp"

namespace crushdem {

namespace {

using Idx = std::ptrdiff_t;

// The first half kick and drift of one grain (step_rules.hpp), the pair loop's packed copies
// written from values already in registers, and the two squared-displacement maxima. Inlined
// into kick_drift() and into the gather pass of the step before (gather_grains<.., kDrift =
// true>), both loops in vector lanes. Constructing it sizes the packed copies to the store.
struct KickDrift {
  double h, hh;
  double spin_scale;  // ContactParams::spin_scale: 0 holds every spin at zero (rotation blocked)
  double *x, *y, *z, *vx, *vy, *vz, *wx, *wy, *wz;
  const double *fx, *fy, *fz, *tx, *ty, *tz, *inv_mass, *inv_inertia, *radius;
  const double *x0, *y0, *z0;  // positions at the last neighbour build
  detail::PackedPosition* P;
  detail::PackedVelocity* V;

  KickDrift(ParticleStore& p, const NeighborList& nl, CpuPairLoop& loop, double dt, double spin)
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
    loop.positions().resize(p.size());
    loop.velocities().resize(p.size());
    P = loop.positions().data();
    V = loop.velocities().data();
  }

  // F and T: the force and torque on the grain (p.fx ... p.tz, or the same values still in
  // registers when fused with the gather pass).
  void operator()(std::size_t i, Vec3 F, Vec3 T, double& since_build2, double& step2) const {
    const double im = inv_mass[i];
    double vx1 = vx[i], vy1 = vy[i], vz1 = vz[i], wx1 = wx[i], wy1 = wy[i], wz1 = wz[i];
    half_kick(hh, spin_scale, im, inv_inertia[i], F, T, vx1, vy1, vz1, wx1, wy1, wz1);
    const double x1 = drifted(x[i], h, vx1);
    const double y1 = drifted(y[i], h, vy1);
    const double z1 = drifted(z[i], h, vz1);
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
    const double s2 = square_displacement(x1, y1, z1, seen.x, seen.y, seen.z);
    const double s2_checked = seen.r == r ? s2 : std::numeric_limits<double>::infinity();
    step2 = step2 < s2_checked ? s2_checked : step2;
    P[i] = {x1, y1, z1, r};
    V[i] = {vx1, vy1, vz1, wx1, wy1, wz1, im, 0.0};
    const double d2 = square_displacement(x1, y1, z1, x0[i], y0[i], z0[i]);
    since_build2 = since_build2 < d2 ? d2 : since_build2;
  }
};

template <bool kDamp, bool kKick, bool kDrift>
DriftMaxima gather_grains(ParticleStore& p, const NeighborList& nl, CpuPairLoop& loop,
                          const WallContacts& wc, double h, double spin_scale, double alpha,
                          Vec3 gravity, std::vector<double>& fu_x, std::vector<double>& fu_y,
                          std::vector<double>& fu_z) {
  static_assert(kKick || !kDrift, "the next step's kick follows this one's");
  const std::size_t N = p.size();
  if (N == 0) return {0.0, 0.0};
  // The sums as a plain array of doubles, eight per grain: GCC vectorises strided access to
  // doubles, not to the fields of an over-aligned struct.
  static_assert(sizeof(detail::PackedForce) == 8 * sizeof(double));
  double* const PF = &loop.force_sums().data()->fx;
  // The store's velocities, inverse masses and inertias through KickDrift's pointers; plain
  // pointers, not restrict ones, since KickDrift also writes the velocities. `omp simd` lets
  // the loop run in vector lanes anyway, each element with the same operations as a scalar
  // loop. kDrift: the next step's first half kick and drift, in the same pass (the step asks for
  // it when nothing changes between the two steps: same dt, no caller in between).
  const KickDrift kd(p, nl, loop, h, spin_scale);
  double* const fux = fu_x.data();
  double* const fuy = fu_y.data();
  double* const fuz = fu_z.data();
  double* const pfx = p.fx.data();
  double* const pfy = p.fy.data();
  double* const pfz = p.fz.data();
  double* const ptx = p.tx.data();
  double* const pty = p.ty.data();
  double* const ptz = p.tz.data();
  const std::uint32_t* const wall_first = wc.offsets.data();
  const bool has_gravity = gravity.x != 0.0 || gravity.y != 0.0 || gravity.z != 0.0;
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
      double* const sum = PF + 8 * std::size_t{wc.particle[e]};
      sum[0] += wc.fx[e];
      sum[1] += wc.fy[e];
      sum[2] += wc.fz[e];
      sum[3] += wc.tx[e];
      sum[4] += wc.ty[e];
      sum[5] += wc.tz[e];
    }
    // The weight after the contacts (as the device adds it); without gravity not at all, so
    // that no zero changes its sign.
    if (has_gravity) {
      for (std::size_t j = share.first; j < share.last; ++j) {
        double* const sum = PF + 8 * j;
        sum[0] += p.mass[j] * gravity.x;
        sum[1] += p.mass[j] * gravity.y;
        sum[2] += p.mass[j] * gravity.z;
      }
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
        damp(alpha, Vec3{kd.vx[j], kd.vy[j], kd.vz[j]}, Vec3{kd.wx[j], kd.wy[j], kd.wz[j]}, F, T);
      }
      pfx[j] = F.x;
      pfy[j] = F.y;
      pfz[j] = F.z;
      ptx[j] = T.x;
      pty[j] = T.y;
      ptz[j] = T.z;
      if constexpr (kKick) {  // second half kick of velocity Verlet (one pass over memory)
        half_kick(kd.hh, kd.spin_scale, kd.inv_mass[j], kd.inv_inertia[j], F, T, kd.vx[j], kd.vy[j],
                  kd.vz[j], kd.wx[j], kd.wy[j], kd.wz[j]);
      }
      if constexpr (kDrift) kd(j, F, T, m2, step2);
    }
  }
  return {m2, step2};
}

}  // namespace

DriftMaxima kick_drift(ParticleStore& p, const NeighborList& nl, CpuPairLoop& loop, double h,
                       double spin_scale) {
  const std::size_t N = p.size();
  const KickDrift kd(p, nl, loop, h, spin_scale);
  double m2 = 0.0, step2 = 0.0;
#pragma omp parallel for simd schedule(static) reduction(max : m2, step2) if (worth_threading(N))
  for (Idx ii = 0; ii < static_cast<Idx>(N); ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    kd(i, Vec3{kd.fx[i], kd.fy[i], kd.fz[i]}, Vec3{kd.tx[i], kd.ty[i], kd.tz[i]}, m2, step2);
  }
  loop.mark_packed();
  return {m2, step2};
}

DriftMaxima gather_and_damp(ParticleStore& p, const NeighborList& nl, CpuPairLoop& loop,
                            const WallContacts& wc, double h, double spin_scale, double alpha,
                            Vec3 gravity, bool kick, bool drift_next, std::vector<double>& fu_x,
                            std::vector<double>& fu_y, std::vector<double>& fu_z) {
  const std::size_t N = p.size();
  fu_x.resize(N);
  fu_y.resize(N);
  fu_z.resize(N);
  const bool damped = alpha > 0.0;
  DriftMaxima next{0.0, 0.0};
  // The pass with the template flags given as std::bool_constant tags.
  const auto gather = [&](auto damp_on, auto kick_on, auto drift_on) {
    return gather_grains<decltype(damp_on)::value, decltype(kick_on)::value,
                         decltype(drift_on)::value>(p, nl, loop, wc, h, spin_scale, alpha, gravity,
                                                    fu_x, fu_y, fu_z);
  };
  const std::true_type yes;
  const std::false_type no;
  if (drift_next) {
    next = damped ? gather(yes, yes, yes) : gather(no, yes, yes);
    loop.mark_packed();
  } else if (damped) {
    kick ? gather(yes, yes, no) : gather(yes, no, no);
  } else {
    kick ? gather(no, yes, no) : gather(no, no, no);
  }
  loop.mark_sums_zero();
  return next;
}

}  // namespace crushdem
