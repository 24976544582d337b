// The GPU time-stepper against the CPU step (plain executable: no GoogleTest on the GPU machine).
// Prints "N passed, M failed" as its last line; exit code 0 only when all pass.
//
//   a) two spheres, head-on Hertz impact: the GPU trajectory follows the CPU's (relative 1e-9)
//      and conserves kinetic energy across the collision;
//   b) a sample of 300 rough grains compressed by six servo walls: 2000 more steps on the CPU
//      and on the GPU give the same positions to within a tolerance (see below), the same
//      neighbour rebuilds, and two GPU runs give identical bits;
//   c) neighbour rebuilds on the GPU path (download, host rebuild by ids, upload): oblique
//      frictional impacts with a tiny skin (rebuilt every few steps, CPU to 1e-9), and the
//      sample of b) under a wall moving at 1 m/s (within the tolerance of b);
//   d) the contact load for crushing (largest contact stress, F_n and its normal per grain) on
//      the sample of b), against the CPU's.
//
// The GPU sums each particle's forces in another order than the CPU (own entries, then reverse
// entries, then walls; the CPU in column order), so the two differ from the first step by
// rounding (1e-16 relative) and the difference grows in a dense packing. The tolerance on
// positions, 1e-6 of the mean radius, is far above what rounding grows to in 2000 steps (the
// printed deviations) and far below any physical displacement (the printed travel).
//
// With --emulate the stepper runs its kernels' bodies on the host (no GPU needed). On a device,
// b) and c) are also run that way and must equal the device's bits.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <numeric>
#include <string>
#include <vector>

#include "../helpers.hpp"
#include "crushdem/core/random.hpp"
#include "crushdem/integrate/gpu_stepper.hpp"
#include "crushdem/integrate/simulation.hpp"
#include "crushdem/particles/generate.hpp"

using namespace crushdem;

namespace {

int passed = 0, failed = 0;

void check(bool ok, const std::string& name, const std::string& detail) {
  std::printf("%s %s: %s\n", ok ? "PASS" : "FAIL", name.c_str(), detail.c_str());
  (ok ? passed : failed)++;
}

std::string fmt(const char* f, double a, double b = 0.0, double c = 0.0, double d = 0.0) {
  char buf[256];
  std::snprintf(buf, sizeof buf, f, a, b, c, d);
  return buf;
}

using crushdem::testing::box_config;  // shared with the C++ tests

// Particle indices sorted by id (the two runs may order particles differently).
std::vector<std::size_t> by_id(const Simulation& s) {
  std::vector<std::size_t> o(s.particles().size());
  std::iota(o.begin(), o.end(), 0);
  std::sort(o.begin(), o.end(), [&](std::size_t a, std::size_t b) {
    return s.particles().id[a] < s.particles().id[b];
  });
  return o;
}

// Largest |x_a - x_b| over particles (matched by id) and coordinates.
double max_position_difference(const Simulation& a, const Simulation& b) {
  const auto oa = by_id(a), ob = by_id(b);
  const ParticleStore &pa = a.particles(), &pb = b.particles();
  double m = 0.0;
  for (std::size_t k = 0; k < oa.size(); ++k) {
    const std::size_t i = oa[k], j = ob[k];
    if (pa.id[i] != pb.id[j]) return INFINITY;
    m = std::max({m, std::fabs(pa.x[i] - pb.x[j]), std::fabs(pa.y[i] - pb.y[j]),
                  std::fabs(pa.z[i] - pb.z[j])});
  }
  return m;
}

double max_velocity_difference(const Simulation& a, const Simulation& b) {
  const auto oa = by_id(a), ob = by_id(b);
  const ParticleStore &pa = a.particles(), &pb = b.particles();
  double m = 0.0;
  for (std::size_t k = 0; k < oa.size(); ++k) {
    const std::size_t i = oa[k], j = ob[k];
    m = std::max({m, std::fabs(pa.vx[i] - pb.vx[j]), std::fabs(pa.vy[i] - pb.vy[j]),
                  std::fabs(pa.vz[i] - pb.vz[j])});
  }
  return m;
}

bool same_bits(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

bool identical(const Simulation& a, const Simulation& b) {
  const ParticleStore &pa = a.particles(), &pb = b.particles();
  if (pa.id != pb.id) return false;
  for (auto m : {&ParticleStore::x, &ParticleStore::y, &ParticleStore::z, &ParticleStore::vx,
                 &ParticleStore::vy, &ParticleStore::vz, &ParticleStore::wx, &ParticleStore::wy,
                 &ParticleStore::wz, &ParticleStore::fx, &ParticleStore::fy, &ParticleStore::fz}) {
    if (!same_bits(pa.*m, pb.*m)) return false;
  }
  for (int k = 0; k < kNumWalls; ++k) {
    if (std::memcmp(&a.walls().state(k), &b.walls().state(k), sizeof(WallState)) != 0) return false;
  }
  return true;
}

double mean_radius(const Simulation& s) {
  const auto& r = s.particles().radius;
  return std::accumulate(r.begin(), r.end(), 0.0) / static_cast<double>(r.size());
}

void run_gpu(Simulation& s, std::uint64_t steps, GpuStepper::Mode mode) {
  GpuStepper g(s, mode);
  g.step(steps);
  g.download();
}

// a) Head-on impact of two equal spheres (as tests/test_impact.cpp).
void test_impact(GpuStepper::Mode mode) {
  SimulationConfig cfg = box_config(-1e-3, 1e-3, NormalLaw::Hertz);
  cfg.timestep.dt = 5e-10;
  Simulation cpu(cfg);
  const double R = 1e-4, v = 0.1;
  cpu.add_particle({-R - 1e-7, 0, 0}, R, {v, 0, 0});
  cpu.add_particle({R + 1e-7, 0, 0}, R, {-v, 0, 0});
  Simulation gpu_sim = cpu;
  GpuStepper gpu(gpu_sim, mode);
  const double ke0 = cpu.kinetic_energy();
  double dx = 0.0, dv = 0.0, max_overlap = 0.0;
  for (int c = 0; c < 60; ++c) {  // 6000 steps: approach (2000), contact (~1650), separation
    cpu.step(100);
    gpu.step(100);
    gpu.download();
    dx = std::max(dx, max_position_difference(cpu, gpu_sim) / R);
    dv = std::max(dv, max_velocity_difference(cpu, gpu_sim) / v);
    const auto& p = gpu_sim.particles();
    max_overlap = std::max(max_overlap, 2.0 * R - std::fabs(p.x[1] - p.x[0]));
  }
  const double ke_gpu = gpu_sim.kinetic_energy(), ke_cpu = cpu.kinetic_energy();
  const auto& p = gpu_sim.particles();
  const bool bounced = p.vx[by_id(gpu_sim)[0]] < -0.99 * v;
  check(dx <= 1e-9 && dv <= 1e-9, "impact: GPU follows the CPU trajectory",
        fmt("max |dx|/R = %.3g, max |dv|/v = %.3g (tolerance 1e-9)", dx, dv));
  check(bounced && max_overlap > 1e-8 && std::fabs(ke_gpu / ke0 - 1.0) < 1e-3,
        "impact: energy conserved across the collision",
        fmt("KE after/before GPU %.9f CPU %.9f, max overlap %.3g m", ke_gpu / ke0, ke_cpu / ke0,
            max_overlap));
}

// c) Oblique grain-grain and grain-wall impacts with friction and spin, with a skin so small
// that the list is rebuilt every few steps during the contacts: the tangential history goes
// through many download / id-keyed rebuild / upload cycles. Each grain has at most one pair and
// one wall contact, so the sums have the CPU's order and the runs must agree to rounding. With
// rolling_friction > 0 the rolling moment and its history go through the same cycles.
void test_rebuild_history(GpuStepper::Mode mode, double rolling_friction = 0.0) {
  const std::string name = rolling_friction > 0.0 ? "rebuilds with rolling" : "rebuilds";
  SimulationConfig cfg = box_config(-1e-3, 1e-3, NormalLaw::Rough);
  cfg.contact.wall_friction = 0.3;
  cfg.contact.rolling_friction = rolling_friction;
  if (rolling_friction > 0.0) cfg.contact.rotation = Rotation::Rolling;
  cfg.timestep.dt = 5e-10;
  cfg.neighbor.skin = 2e-9;
  Simulation cpu(cfg);
  const double R = 1e-4, v = 0.1, gap = 4e-8, dy = 0.5 * R;
  const double dx = std::sqrt((2 * R + gap) * (2 * R + gap) - dy * dy);
  cpu.add_particle({-0.5 * dx, 0, 0}, R, {v, 0, 0}, {0, 0, 300});
  cpu.add_particle({0.5 * dx, dy, 0}, R, {-v, 0.2 * v, 0}, {100, 0, 0});
  cpu.add_particle({5e-4, 5e-4, -1e-3 + R + gap}, R, {0.5 * v, 0, -v}, {200, 0, 0});
  Simulation gpu_sim = cpu;
  GpuStepper gpu(gpu_sim, mode);
  const std::size_t builds0 = cpu.neighbors().builds();
  double ex = 0.0, ev = 0.0, ew = 0.0, max_ft = 0.0, max_mr = 0.0;
  for (int c = 0; c < 30; ++c) {  // 6000 steps: both collisions start after ~400 steps
    cpu.step(200);
    gpu.step(200);
    gpu.download();
    ex = std::max(ex, max_position_difference(cpu, gpu_sim) / R);
    ev = std::max(ev, max_velocity_difference(cpu, gpu_sim) / v);
    const auto oa = by_id(cpu), ob = by_id(gpu_sim);
    const ParticleStore &pa = cpu.particles(), &pb = gpu_sim.particles();
    for (std::size_t k = 0; k < oa.size(); ++k) {
      const std::size_t i = oa[k], j = ob[k];
      ew = std::max({ew, std::fabs(pa.wx[i] - pb.wx[j]) * R / v,
                     std::fabs(pa.wy[i] - pb.wy[j]) * R / v,
                     std::fabs(pa.wz[i] - pb.wz[j]) * R / v});
    }
    for (const ContactRecord& r : gpu_sim.contacts()) {
      max_ft = std::max(max_ft, norm(r.F_t));
      max_mr = std::max(max_mr, norm(r.M_r));
    }
  }
  const std::size_t builds = gpu_sim.neighbors().builds() - builds0;
  check(ex <= 1e-9 && ev <= 1e-9 && ew <= 1e-9,
        name + ": oblique impacts follow the CPU through the rebuilds",
        fmt("max |dx|/R = %.3g, |dv|/v = %.3g, |dw| R/v = %.3g (tolerance 1e-9)", ex, ev, ew));
  check(builds >= 50 && builds == cpu.neighbors().builds() - builds0 && max_ft > 0.0 &&
            (rolling_friction > 0.0) == (max_mr > 0.0),
        name + ": the list was rebuilt during frictional contacts",
        fmt("%.0f rebuilds (CPU %.0f), largest tangential force %.3g N, rolling moment %.3g N m",
            static_cast<double>(builds), static_cast<double>(cpu.neighbors().builds() - builds0),
            max_ft, max_mr));
}

// A loose sample of 300 grains compressed by six servo walls on the CPU.
Simulation compressed_sample() {
  const double L = 1.25e-3;
  SimulationConfig cfg = box_config(0.0, L, NormalLaw::Rough);
  cfg.damping.local_alpha = 0.7;
  cfg.neighbor.skin = 5e-6;  // a tenth of the smallest radius: frequent rebuilds
  for (auto& w : cfg.walls) {
    w.mode = WallMode::Servo;
    w.target_stress = 5e5;
    w.max_speed = 2.0;
  }
  Simulation s(cfg);
  RandomStream rng(3, 0xD1A);
  std::vector<double> radii(300);
  for (double& r : radii) r = 0.5 * rng.uniform(0.1e-3, 0.2e-3);
  for (const PlacedSphere& p : random_sequential_addition(radii, {0, L, 0, L, 0, L}, 3)) {
    s.add_particle(p.position, p.radius);
  }
  s.step(20000);
  s.set_dt(s.dt());  // the GPU keeps the step fixed; so must the CPU for a comparison
  return s;
}

void compare_runs(const char* name, const Simulation& start, std::uint64_t steps,
                  GpuStepper::Mode mode, bool expect_rebuilds) {
  Simulation cpu = start, g1 = start, g2 = start, pert = start;
  const std::size_t builds0 = start.neighbors().builds();
  cpu.step(steps);
  // The chaos baseline: the CPU run again with one coordinate changed by one rounding step.
  pert.particles().x[0] = std::nextafter(pert.particles().x[0], 1.0);
  pert.step(steps);
  run_gpu(g1, steps, mode);
  run_gpu(g2, steps, mode);
  const double r = mean_radius(start);
  const double dev = max_position_difference(cpu, g1) / r;
  const double travel = max_position_difference(cpu, start) / r;
  const std::size_t bc = cpu.neighbors().builds() - builds0, bg = g1.neighbors().builds() - builds0;
  double dwall = 0.0;
  for (int k = 0; k < kNumWalls; ++k) {
    dwall = std::max(dwall, std::fabs(cpu.walls().position(k) - g1.walls().position(k)) / r);
  }
  check(dev < 1e-6 && dwall < 1e-6, std::string(name) + ": GPU positions agree with the CPU",
        fmt("max |dx|/r_mean = %.3g, walls %.3g (tolerance 1e-6); largest travel %.3g r_mean", dev,
            dwall, travel));
  std::printf("  %s: CPU run with x_0 moved by one ulp deviates by %.3g r_mean\n", name,
              max_position_difference(cpu, pert) / r);
  check(bc == bg && (!expect_rebuilds || bg >= 2),
        std::string(name) + ": same neighbour rebuilds as the CPU",
        fmt("CPU %.0f, GPU %.0f rebuilds", static_cast<double>(bc), static_cast<double>(bg)));
  check(identical(g1, g2), std::string(name) + ": two GPU runs are bit-identical",
        "positions, velocities, forces and walls");
  if (mode == GpuStepper::Mode::Device) {
    Simulation g3 = start;
    run_gpu(g3, steps, GpuStepper::Mode::HostEmulation);
    check(identical(g1, g3), std::string(name) + ": device equals the host emulation bit for bit",
          "positions, velocities, forces and walls");
  }
  std::printf("  %s: %zu particles, %zu contacts, mean wall stress %.4g Pa\n", name,
              g1.particles().size(), g1.num_contacts(), [&] {
                double s = 0.0;
                for (int k = 0; k < kNumWalls; ++k) s += g1.walls().stress(k) / kNumWalls;
                return s;
              }());
}

// d) Contact-load tracking for crushing (Simulation::track_contact_load): after 2000 steps of the
// sample of b) the GPU's per-grain largest contact stress, largest elastic F_n and its normal
// equal the CPU's (to the tolerance the positions agree to, relative to the largest value); on a
// device also bit for bit the host emulation's.
void compare_load(const Simulation& sample, std::uint64_t steps, GpuStepper::Mode mode) {
  Simulation start = sample;
  start.track_contact_load(1.0);
  Simulation cpu = start, g1 = start;
  cpu.step(steps);
  run_gpu(g1, steps, mode);
  const auto oc = by_id(cpu), og = by_id(g1);
  const Simulation::ContactLoad &Lc = cpu.contact_load(), &Lg = g1.contact_load();
  const std::size_t N = oc.size();
  bool sizes = Lg.sigma.size() == N && Lg.F_n_max.size() == N && Lg.nx.size() == N &&
               Lg.ny.size() == N && Lg.nz.size() == N;
  double s_max = 0.0, F_max = 0.0, ds = 0.0, dF = 0.0, dn = 0.0;
  std::size_t loaded = 0;
  if (sizes) {
    for (std::size_t k = 0; k < N; ++k) {
      s_max = std::max(s_max, Lc.sigma[oc[k]]);
      F_max = std::max(F_max, Lc.F_n_max[oc[k]]);
    }
    for (std::size_t k = 0; k < N; ++k) {
      const std::size_t i = oc[k], j = og[k];
      ds = std::max(ds, std::fabs(Lc.sigma[i] - Lg.sigma[j]) / s_max);
      dF = std::max(dF, std::fabs(Lc.F_n_max[i] - Lg.F_n_max[j]) / F_max);
      if (Lc.F_n_max[i] > 0.0) {
        ++loaded;
        dn = std::max({dn, std::fabs(Lc.nx[i] - Lg.nx[j]), std::fabs(Lc.ny[i] - Lg.ny[j]),
                       std::fabs(Lc.nz[i] - Lg.nz[j])});
      }
    }
  }
  check(sizes && s_max > 0.0 && loaded > N / 2 && ds < 1e-6 && dF < 1e-6 && dn < 1e-6,
        "contact load: GPU maxima equal the CPU's",
        fmt("%.0f of %.0f grains loaded; max difference sigma %.3g, F_n %.3g (of the largest), ",
            static_cast<double>(loaded), static_cast<double>(N), ds, dF) +
            fmt("normal %.3g (tolerance 1e-6); largest sigma_c %.4g Pa", dn, s_max));
  if (mode == GpuStepper::Mode::Device) {
    Simulation g3 = start;
    run_gpu(g3, steps, GpuStepper::Mode::HostEmulation);
    const Simulation::ContactLoad& Le = g3.contact_load();
    check(same_bits(Lg.sigma, Le.sigma) && same_bits(Lg.F_n_max, Le.F_n_max) &&
              same_bits(Lg.nx, Le.nx) && same_bits(Lg.ny, Le.ny) && same_bits(Lg.nz, Le.nz),
          "contact load: device equals the host emulation bit for bit", "sigma, F_n, normal");
  }
}

}  // namespace

int main(int argc, char** argv) {
  const bool emulate = argc > 1 && std::strcmp(argv[1], "--emulate") == 0;
  if (!emulate && !GpuStepper::available()) {
    std::printf("no CUDA device (run with --emulate to check the logic on the host)\n");
    std::printf("0 passed, 1 failed\n");
    return 1;
  }
  const auto mode = emulate ? GpuStepper::Mode::HostEmulation : GpuStepper::Mode::Device;
  std::printf("mode: %s\n", emulate ? "host emulation" : "CUDA device");
  try {
    test_impact(mode);
    test_rebuild_history(mode);
    test_rebuild_history(mode, 0.2);
    const Simulation sample = compressed_sample();
    compare_runs("compressed sample", sample, 2000, mode, false);
    Simulation moving = sample;
    moving.walls().config(3).mode = WallMode::Velocity;  // ymax pushes in at 1 m/s
    moving.walls().config(3).velocity = -1.0;
    compare_runs("moving wall", moving, 2000, mode, true);
    compare_load(sample, 2000, mode);
  } catch (const std::exception& e) {
    check(false, "exception", e.what());
  }
  std::printf("%d passed, %d failed\n", passed, failed);
  return failed == 0 ? 0 : 1;
}
