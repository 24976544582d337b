#include "crushdem/walls/wall_forces.hpp"

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>

#include "crushdem/contact/contact_kernel.hpp"
#include "crushdem/core/deterministic.hpp"

namespace crushdem {

namespace {
using Idx = std::ptrdiff_t;

template <class Law>
void wall_forces_with(const Law& law, const ContactParams& params, double h, const ParticleStore& p,
                      Walls& walls, WallContacts& wc) {
  const std::size_t M = wc.size();
  const ContactParams cp = params;
  const int bodies = walls.size();
  const BodyShape* const shape = walls.shapes().data();
  std::array<double, kMaxBodies> pos{}, vel{};
  for (int k = 0; k < bodies; ++k) {
    pos[static_cast<std::size_t>(k)] = walls.position(k);
    vel[static_cast<std::size_t>(k)] = walls.state(k).velocity;
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
    enum : std::size_t { NX, NY, NZ, DIST, DELTA, RSTAR, MASS, VX, VY, VZ, WX, WY, WZ, UX, UY, UZ,
                         MU, FTX, FTY, FTZ, FX, FY, FZ, TX, TY, TZ, FNW, KN, kFields };
    // clang-format on
    alignas(64) double in[kFields][kChunk];
    std::uint32_t slot_entry[kChunk];
    std::size_t n = 0;
    for (std::size_t e = first; e < last; ++e) {
      const std::size_t i = wc.particle[e];
      const auto ks = static_cast<std::size_t>(wc.wall[e]);
      const BodyContact bc =
          body_contact(shape[ks], pos[ks], vel[ks], {p.x[i], p.y[i], p.z[i]}, p.radius[i]);
      const double dist = bc.dist;
      const double delta = p.radius[i] - dist;
      if (delta <= 0.0) {
        wc.ft_x[e] = wc.ft_y[e] = wc.ft_z[e] = 0.0;
        wc.fx[e] = wc.fy[e] = wc.fz[e] = wc.tx[e] = wc.ty[e] = wc.tz[e] = 0.0;
        wc.F_n[e] = wc.k_n[e] = wc.delta[e] = 0.0;
        continue;
      }
      const Vec3 nk = bc.n;
      const Vec3 u = bc.velocity;
      slot_entry[n] = static_cast<std::uint32_t>(e);
      in[NX][n] = nk.x;
      in[NY][n] = nk.y;
      in[NZ][n] = nk.z;
      in[DIST][n] = dist;
      in[DELTA][n] = delta;
      in[RSTAR][n] = bc.R_star;
      in[MASS][n] = p.mass[i];
      in[VX][n] = p.vx[i];
      in[VY][n] = p.vy[i];
      in[VZ][n] = p.vz[i];
      in[WX][n] = p.wx[i];
      in[WY][n] = p.wy[i];
      in[WZ][n] = p.wz[i];
      in[UX][n] = u.x;
      in[UY][n] = u.y;
      in[UZ][n] = u.z;
      in[MU][n] = shape[ks].friction;
      in[FTX][n] = wc.ft_x[e];
      in[FTY][n] = wc.ft_y[e];
      in[FTZ][n] = wc.ft_z[e];
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
    double* __restrict const wRSTAR = in[RSTAR];
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
    double* __restrict const wMU = in[MU];
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
          law_private, Vec3{wNX[m], wNY[m], wNZ[m]}, wDIST[m], wDELTA[m], wRSTAR[m], wMASS[m],
          Vec3{wVX[m], wVY[m], wVZ[m]}, Vec3{wWX[m], wWY[m], wWZ[m]}, Vec3{wUX[m], wUY[m], wUZ[m]},
          Vec3{wFTX[m], wFTY[m], wFTZ[m]}, wMU[m], cp_private, h);
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
    // The results back to their entries, column by column.
    const std::pair<std::vector<double>*, std::size_t> results[] = {
        {&wc.ft_x, FTX}, {&wc.ft_y, FTY}, {&wc.ft_z, FTZ}, {&wc.fx, FX},
        {&wc.fy, FY},    {&wc.fz, FZ},    {&wc.tx, TX},    {&wc.ty, TY},
        {&wc.tz, TZ},    {&wc.F_n, FNW},  {&wc.k_n, KN},   {&wc.delta, DELTA}};
    for (const auto& [column, field] : results) {
      double* const to = column->data();
      const double* const from = in[field];
      for (std::size_t m = 0; m < n; ++m) to[slot_entry[m]] = from[m];
    }
  }
  // Body totals in entry order (deterministic; wall entries are few).
  for (int k = 0; k < bodies; ++k) {
    WallState& s = walls.state(k);
    s.normal_force = 0.0;
    s.force = {};
    s.stiffness = 0.0;
  }
  for (std::size_t e = 0; e < M; ++e) {
    WallState& s = walls.state(wc.wall[e]);
    s.normal_force += wc.F_n[e];
    s.force -= Vec3{wc.fx[e], wc.fy[e], wc.fz[e]};
    s.stiffness += wc.k_n[e];
  }
}

}  // namespace

void wall_forces(const ContactLaw& law, double h, const ParticleStore& p, Walls& walls,
                 WallContacts& wc) {
  with_law(law,
           [&](const auto& model) { wall_forces_with(model.wall_law, model.cp, h, p, walls, wc); });
}

}  // namespace crushdem
