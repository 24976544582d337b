// The device step against the CPU engine, for any device (backend/device_api.hpp): the host
// emulation in the default test suite (test_device_step.cpp) and the GPU in
// tests/cuda/test_device.cpp, which also compares the GPU's bits with the emulation's.
//
// The device sums each grain's forces in another order than the CPU (own entries, then reverse
// entries, then walls; the CPU in column order), so the two differ from the first step by
// rounding (1e-16 relative) and the difference grows in a dense packing. Where a grain has at
// most one contact of each kind the order cannot differ, and the runs agree to 1e-9. In a dense
// sample the tolerance on positions, 1e-6 of the mean radius over 2,000 steps, is far above what
// rounding grows to in that time (the detail prints the deviation of a CPU run whose first
// coordinate was moved by one ulp: the same growth) and far below any physical displacement.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <memory>
#include <numeric>
#include <string>
#include <vector>

#include "box_config.hpp"
#include "crushdem/backend/device_stepper.hpp"
#include "crushdem/core/error.hpp"
#include "crushdem/core/random.hpp"
#include "crushdem/experiments/measurements.hpp"
#include "crushdem/fracture/crushing.hpp"
#include "crushdem/integrate/simulation.hpp"
#include "crushdem/particles/generate.hpp"

namespace crushdem::device_checks {

struct Check {
  bool ok;
  std::string name, detail;
};
using ApiFactory = std::function<std::unique_ptr<device::Api>()>;

inline std::string fmt(const char* f, double a, double b = 0.0, double c = 0.0, double d = 0.0) {
  char buf[256];
  std::snprintf(buf, sizeof buf, f, a, b, c, d);
  return buf;
}

using testing::box_config;

/// Particle indices sorted by id (two runs may order particles differently).
inline std::vector<std::size_t> by_id(const Simulation& s) {
  std::vector<std::size_t> o(s.particles().size());
  std::iota(o.begin(), o.end(), std::size_t{0});
  std::sort(o.begin(), o.end(), [&](std::size_t a, std::size_t b) {
    return s.particles().id[a] < s.particles().id[b];
  });
  return o;
}

/// Largest |a - b| of a per-grain array over grains matched by id (infinite if they differ).
inline double max_difference(const Simulation& a, const Simulation& b,
                             std::vector<double> ParticleStore::*m) {
  const auto oa = by_id(a), ob = by_id(b);
  const ParticleStore &pa = a.particles(), &pb = b.particles();
  if (oa.size() != ob.size()) return INFINITY;
  double d = 0.0;
  for (std::size_t k = 0; k < oa.size(); ++k) {
    if (pa.id[oa[k]] != pb.id[ob[k]]) return INFINITY;
    d = std::max(d, std::fabs((pa.*m)[oa[k]] - (pb.*m)[ob[k]]));
  }
  return d;
}

inline double max_position_difference(const Simulation& a, const Simulation& b) {
  return std::max({max_difference(a, b, &ParticleStore::x), max_difference(a, b, &ParticleStore::y),
                   max_difference(a, b, &ParticleStore::z)});
}

inline double max_velocity_difference(const Simulation& a, const Simulation& b) {
  return std::max({max_difference(a, b, &ParticleStore::vx),
                   max_difference(a, b, &ParticleStore::vy),
                   max_difference(a, b, &ParticleStore::vz)});
}

inline bool same_bits(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

/// The same state to the bit: grains, motion, forces, walls and clock.
inline bool identical(const Simulation& a, const Simulation& b) {
  const ParticleStore &pa = a.particles(), &pb = b.particles();
  if (pa.id != pb.id || a.time() != b.time() || a.step_count() != b.step_count()) return false;
  for (auto m : {&ParticleStore::x, &ParticleStore::y, &ParticleStore::z, &ParticleStore::vx,
                 &ParticleStore::vy, &ParticleStore::vz, &ParticleStore::wx, &ParticleStore::wy,
                 &ParticleStore::wz, &ParticleStore::fx, &ParticleStore::fy, &ParticleStore::fz}) {
    if (!same_bits(pa.*m, pb.*m)) return false;
  }
  for (int k = 0; k < kNumWalls; ++k) {
    const WallState &u = a.walls().state(k), &v = b.walls().state(k);
    if (u.position != v.position || u.velocity != v.velocity || u.normal_force != v.normal_force)
      return false;
  }
  return true;
}

inline double mean_radius(const Simulation& s) {
  const auto& r = s.particles().radius;
  return std::accumulate(r.begin(), r.end(), 0.0) / static_cast<double>(r.size());
}

/// `steps` steps of `s` on a fresh device, then the host copy made current.
inline void run_device(Simulation& s, std::uint64_t steps, const ApiFactory& api) {
  DeviceStepper d(api());
  d.advance(s, steps);
  d.sync(s);
}

/// a) Head-on impact of two equal spheres (as tests/test_impact.cpp): the device follows the
/// CPU trajectory and conserves kinetic energy across the collision.
inline std::vector<Check> impact(const ApiFactory& api) {
  SimulationConfig cfg = box_config(-1e-3, 1e-3, NormalLaw::Hertz);
  cfg.timestep.dt = 5e-10;
  Simulation cpu(cfg);
  const double R = 1e-4, v = 0.1;
  cpu.add_particle({-R - 1e-7, 0, 0}, R, {v, 0, 0});
  cpu.add_particle({R + 1e-7, 0, 0}, R, {-v, 0, 0});
  Simulation dev = cpu;
  DeviceStepper d(api());
  const double ke0 = cpu.kinetic_energy();
  double dx = 0.0, dv = 0.0, max_overlap = 0.0;
  for (int c = 0; c < 60; ++c) {  // 6000 steps: approach (2000), contact (~1650), separation
    cpu.step(100);
    d.advance(dev, 100);
    d.sync(dev);
    dx = std::max(dx, max_position_difference(cpu, dev) / R);
    dv = std::max(dv, max_velocity_difference(cpu, dev) / v);
    const auto& p = dev.particles();
    max_overlap = std::max(max_overlap, 2.0 * R - std::fabs(p.x[1] - p.x[0]));
  }
  const double ke = dev.kinetic_energy();
  const bool bounced = dev.particles().vx[by_id(dev)[0]] < -0.99 * v;
  return {{dx <= 1e-9 && dv <= 1e-9 && dev.time() == cpu.time(),
           "impact: the device follows the CPU trajectory",
           fmt("max |dx|/R = %.3g, max |dv|/v = %.3g (tolerance 1e-9)", dx, dv)},
          {bounced && max_overlap > 1e-8 && std::fabs(ke / ke0 - 1.0) < 1e-3,
           "impact: energy conserved across the collision",
           fmt("KE after/before %.9f, max overlap %.3g m", ke / ke0, max_overlap)}};
}

/// b) Oblique grain-grain and grain-wall impacts with friction and spin, with a skin so small
/// that the list is rebuilt every few steps during the contacts: the tangential (and rolling)
/// history goes through many rebuilds on the host and uploads. Each grain has at most one pair
/// and one wall contact, so the sums have the CPU's order and the runs agree to rounding.
inline std::vector<Check> rebuild_history(const ApiFactory& api, double rolling_friction) {
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
  Simulation dev = cpu;
  DeviceStepper d(api());
  const std::size_t builds0 = cpu.neighbors().builds();
  double ex = 0.0, ev = 0.0, ew = 0.0, max_ft = 0.0, max_mr = 0.0;
  for (int c = 0; c < 30; ++c) {  // 6000 steps: both collisions start after ~400 steps
    cpu.step(200);
    d.advance(dev, 200);
    d.sync(dev);
    ex = std::max(ex, max_position_difference(cpu, dev) / R);
    ev = std::max(ev, max_velocity_difference(cpu, dev) / v);
    ew = std::max({ew, max_difference(cpu, dev, &ParticleStore::wx) * R / v,
                   max_difference(cpu, dev, &ParticleStore::wy) * R / v,
                   max_difference(cpu, dev, &ParticleStore::wz) * R / v});
    for (const ContactRecord& r : dev.contacts()) {
      max_ft = std::max(max_ft, norm(r.F_t));
      max_mr = std::max(max_mr, norm(r.M_r));
    }
  }
  const std::size_t builds = dev.neighbors().builds() - builds0;
  return {{ex <= 1e-9 && ev <= 1e-9 && ew <= 1e-9,
           name + ": oblique impacts follow the CPU through the rebuilds",
           fmt("max |dx|/R = %.3g, |dv|/v = %.3g, |dw| R/v = %.3g (tolerance 1e-9)", ex, ev, ew)},
          {builds >= 50 && builds == cpu.neighbors().builds() - builds0 && max_ft > 0.0 &&
               (rolling_friction > 0.0) == (max_mr > 0.0),
           name + ": the list was rebuilt during frictional contacts",
           fmt("%.0f rebuilds (CPU %.0f), largest tangential force %.3g N, rolling moment "
               "%.3g N m",
               static_cast<double>(builds), static_cast<double>(cpu.neighbors().builds() - builds0),
               max_ft, max_mr)}};
}

/// A loose sample of 300 rough grains compressed by six servo walls on the CPU. safety: the
/// automatic time step's factor on sqrt(m / k) (a small one makes the step follow the contacts
/// rather than the Rayleigh time).
inline Simulation compressed_sample(double safety = 0.3) {
  const double L = 1.25e-3;
  SimulationConfig cfg = box_config(0.0, L, NormalLaw::Rough);
  cfg.timestep.safety = safety;
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
  return s;
}

/// c) A dense sample: the device agrees with the CPU to the tolerance above, rebuilds when the
/// CPU does, and two device runs are bit-identical. With `automatic` the time step is chosen on
/// the host every update_interval steps, as the CPU chooses it.
inline std::vector<Check> compare_runs(const std::string& name, const Simulation& sample,
                                       std::uint64_t steps, const ApiFactory& api,
                                       bool expect_rebuilds) {
  Simulation cpu = sample, d1 = sample, d2 = sample, pert = sample;
  const std::size_t builds0 = sample.neighbors().builds();
  cpu.step(steps);
  // The chaos baseline: the CPU run again with one coordinate moved by one rounding step.
  pert.particles().x[0] = std::nextafter(pert.particles().x[0], 1.0);
  pert.invalidate();
  pert.step(steps);
  run_device(d1, steps, api);
  run_device(d2, steps, api);
  const double r = mean_radius(sample);
  const double dev = max_position_difference(cpu, d1) / r;
  const double travel = max_position_difference(cpu, sample) / r;
  const std::size_t bc = cpu.neighbors().builds() - builds0, bd = d1.neighbors().builds() - builds0;
  double dwall = 0.0;
  for (int k = 0; k < kNumWalls; ++k) {
    dwall = std::max(dwall, std::fabs(cpu.walls().position(k) - d1.walls().position(k)) / r);
  }
  const double ddt = std::fabs(cpu.current_dt() / d1.current_dt() - 1.0);
  return {{dev < 1e-6 && dwall < 1e-6 && ddt < 1e-6 && cpu.step_count() == d1.step_count(),
           name + ": positions agree with the CPU",
           fmt("max |dx|/r_mean = %.3g, walls %.3g, dt %.3g (tolerance 1e-6); largest travel %.3g "
               "r_mean",
               dev, dwall, ddt, travel) +
               fmt("; a CPU run with x_0 moved by one ulp deviates by %.3g r_mean",
                   max_position_difference(cpu, pert) / r)},
          {bc == bd && (!expect_rebuilds || bd >= 2), name + ": the same neighbour rebuilds",
           fmt("CPU %.0f, device %.0f rebuilds", static_cast<double>(bc), static_cast<double>(bd))},
          {identical(d1, d2), name + ": two device runs are bit-identical",
           "positions, velocities, forces, walls and clock"}};
}

/// d) Contact-load tracking for crushing: the device's per-grain largest contact stress,
/// largest elastic F_n and its normal equal the CPU's (to the tolerance of c).
inline std::vector<Check> compare_load(const Simulation& sample, std::uint64_t steps,
                                       const ApiFactory& api) {
  Simulation start = sample;
  start.track_contact_load(1.0);
  Simulation cpu = start, dev = start;
  cpu.step(steps);
  run_device(dev, steps, api);
  const auto oc = by_id(cpu), od = by_id(dev);
  const ContactLoad &Lc = cpu.contact_load(), &Ld = dev.contact_load();
  const std::size_t N = oc.size();
  const bool sizes = Ld.sigma.size() == N && Ld.F_n_max.size() == N && Ld.nx.size() == N &&
                     Ld.ny.size() == N && Ld.nz.size() == N;
  double s_max = 0.0, F_max = 0.0, ds = 0.0, dF = 0.0, dn = 0.0;
  std::size_t loaded = 0;
  if (sizes) {
    for (std::size_t k = 0; k < N; ++k) {
      s_max = std::max(s_max, Lc.sigma[oc[k]]);
      F_max = std::max(F_max, Lc.F_n_max[oc[k]]);
    }
    for (std::size_t k = 0; k < N; ++k) {
      const std::size_t i = oc[k], j = od[k];
      ds = std::max(ds, std::fabs(Lc.sigma[i] - Ld.sigma[j]) / s_max);
      dF = std::max(dF, std::fabs(Lc.F_n_max[i] - Ld.F_n_max[j]) / F_max);
      if (Lc.F_n_max[i] > 0.0) {
        ++loaded;
        dn = std::max({dn, std::fabs(Lc.nx[i] - Ld.nx[j]), std::fabs(Lc.ny[i] - Ld.ny[j]),
                       std::fabs(Lc.nz[i] - Ld.nz[j])});
      }
    }
  }
  return {{sizes && s_max > 0.0 && loaded > N / 2 && ds < 1e-6 && dF < 1e-6 && dn < 1e-6,
           "contact load: the device's maxima equal the CPU's",
           fmt("%.0f of %.0f grains loaded; max difference sigma %.3g, F_n %.3g (of the largest), ",
               static_cast<double>(loaded), static_cast<double>(N), ds, dF) +
               fmt("normal %.3g (tolerance 1e-6); largest sigma_c %.4g Pa", dn, s_max)}};
}

/// e) Changes made on the host between steps reach the device: after a sync, a wall switched
/// to a prescribed velocity, a servo target, the friction and one grain's velocity are changed
/// on both copies; the device run then follows the CPU run with those changes, and only the
/// changed fields were uploaded.
inline std::vector<Check> host_changes(const Simulation& sample, const ApiFactory& api) {
  Simulation cpu = sample, dev = sample;
  DeviceStepper d(api());
  cpu.step(500);
  d.advance(dev, 500);
  d.sync(dev);
  const std::uint64_t full0 = d.full_uploads();
  const auto change = [](Simulation& s) {
    s.walls().config(3).mode = WallMode::Velocity;
    s.walls().config(3).velocity = -0.5;
    s.walls().config(0).target_stress = 8e5;
    s.set_friction(0.1);
    const std::size_t i = by_id(s)[7];
    s.particles().vx[i] += 0.01;
  };
  change(cpu);
  change(dev);
  cpu.step(1000);
  d.advance(dev, 1000);
  d.sync(dev);
  const double r = mean_radius(sample);
  const double dx = max_position_difference(cpu, dev) / r;
  const double moved = std::fabs(dev.walls().position(3) - sample.walls().position(3)) / r;
  return {
      {dx < 1e-6 && moved > 1e-3 && dev.contact_params().mu == 0.1,
       "host changes: walls, friction and a velocity set between steps reach the device",
       fmt("max |dx|/r_mean = %.3g (tolerance 1e-6); ymax moved %.3g r_mean", dx, moved)},
      {d.field_uploads() > 0, "host changes: uploaded as changed fields",
       fmt("%.0f field uploads, %.0f full uploads after the change (rebuilds)",
           static_cast<double>(d.field_uploads()), static_cast<double>(d.full_uploads() - full0))}};
}

/// f) Crushing on the device: the sample with weak grains and crack growth under servo walls;
/// the device checks every grain each step, stops when one fails, and the host splits it. The
/// first breakages (grain, step, cause) equal the CPU's, and both runs repeat bit for bit.
inline std::vector<Check> crushing(const Simulation& sample, const ApiFactory& api) {
  CrushingConfig cc;
  cc.enabled = true;
  cc.sigma_lim0 = 1.4e9;
  cc.crack_growth = true;
  cc.v0 = 2000.0;
  const auto run = [&](bool device, std::vector<BreakageEvent>& events) {
    Simulation s = sample;
    for (int k = 0; k < kNumWalls; ++k) s.walls().config(k).target_stress = 3e6;
    Crusher crusher(cc, SplitPattern::default14());
    crusher.begin(s);
    std::unique_ptr<Stepper> st;
    if (device) {
      st = std::make_unique<DeviceStepper>(api());
    } else {
      st = std::make_unique<CpuStepper>();
    }
    st->attach_crusher(&crusher, [&](const std::vector<BreakageEvent>& e) {
      events.insert(events.end(), e.begin(), e.end());
    });
    st->advance(s, 800);
    st->sync(s);
    return s;
  };
  std::vector<BreakageEvent> ec, ed, ed2;
  const Simulation cpu = run(false, ec);
  const Simulation dev = run(true, ed);
  const Simulation dev2 = run(true, ed2);
  std::size_t same = 0;
  while (same < std::min(ec.size(), ed.size()) && ec[same].id == ed[same].id &&
         ec[same].step == ed[same].step && ec[same].cause == ed[same].cause) {
    ++same;
  }
  std::size_t crack = 0;
  for (const BreakageEvent& e : ed) crack += e.cause == BreakCause::Crack ? 1 : 0;
  // Over these 800 steps the runs agree to rounding, so the breakages should all be the same;
  // three quarters leaves room for a grain that reaches its strength within rounding.
  return {{ec.size() >= 10 && 4 * same >= 3 * ec.size() && crack > 0 && crack < ed.size(),
           "crushing: the device breaks the grains the CPU breaks",
           fmt("CPU %.0f breakages, device %.0f (%.0f by crack growth); the first %.0f equal "
               "(grain, step, cause)",
               static_cast<double>(ec.size()), static_cast<double>(ed.size()),
               static_cast<double>(crack), static_cast<double>(same))},
          {identical(dev, dev2) && ed.size() == ed2.size(),
           "crushing: two device runs are bit-identical", "grains, motion, forces, walls"}};
}

/// g) The NaN rule: a grain thrown to a non-finite position is reported by id, as the CPU
/// engine reports it, not lost in a maximum.
inline std::vector<Check> nan_rule(const Simulation& sample, const ApiFactory& api) {
  Simulation dev = sample;
  const std::size_t i = by_id(dev)[11];
  const ParticleId id = dev.particles().id[i];
  dev.particles().vx[i] = std::nan("");
  std::string message;
  try {
    run_device(dev, 10, api);
  } catch (const RuntimeFailure& e) {
    message = e.what();
  }
  const std::string want = "particle id " + std::to_string(id) + " has a non-finite position";
  return {{message.find(want) != std::string::npos,
           "NaN rule: a non-finite position is reported by grain", message}};
}

/// h) The inspection: the scalars a controller's check reads, reduced on the device, equal the
/// host's computation on the same state to rounding, and a light sync (Sync::Clock) leaves the
/// run as a full one would, also where host code asks for the automatic time step after the
/// sync (as a stage with a duration does) at a step where it is due.
inline std::vector<Check> inspection(const ApiFactory& api) {
  const Simulation sample = compressed_sample(0.05);  // the time step follows the contacts
  Simulation light = sample, full = sample;
  std::vector<double> steps;  // the time steps chosen, to show they moved
  DeviceStepper dl(api()), df(api());
  double from_device = 0.0;
  for (int c = 0; c < 6; ++c) {
    dl.advance(light, 500);  // two chunks per timestep.update_interval (1,000 steps)
    dl.sync(light, Sync::Clock);
    from_device = unbalanced_force_ratio(light);  // the device's inspection
    light.dt();
    df.advance(full, 500);
    df.sync(full, Sync::All);
    full.dt();
    steps.push_back(full.current_dt());
  }
  dl.sync(light, Sync::All);
  Simulation host = full;
  host.set_inspection({});  // none: computed from the host's arrays
  const double on_host = unbalanced_force_ratio(host);
  const double rel = std::fabs(from_device / on_host - 1.0);
  return {
      {light.current_inspection() != nullptr && rel < 1e-9,
       "inspection: the device's unbalanced-force ratio equals the host's",
       fmt("device %.12g, host %.12g (relative %.3g; tolerance 1e-9)", from_device, on_host, rel)},
      {identical(light, full) && steps.front() != steps.back(),
       "inspection: light syncs leave the run as full ones do",
       fmt("3,000 steps, synced every 500 by Sync::Clock or Sync::All, the automatic step chosen "
           "every 1,000 from the contacts (%.6g to %.6g s)",
           steps.front(), steps.back())}};
}

/// Every check on the device `api` makes.
/// 100 grains in the lower part of a box of side 3 L about [-L, 2 L], run `steps` steps on the CPU
/// and twice on the device: the device follows the CPU (positions and the bodies' degrees of
/// freedom to 1e-6 of the mean radius), rebuilds when the CPU does, repeats itself bit for bit,
/// and the bodies `moved` have moved (`what` names the case).
/// body_checks' sample: 100 grains placed at random in the lower part of the box of `cfg`
/// (side 3 L about [-L, 2 L]), with half the automatic time step fixed.
inline Simulation body_sample(const SimulationConfig& cfg) {
  const double L = 1.25e-3;
  Simulation sample(cfg);
  RandomStream rng(5, 0xB0D);
  std::vector<double> radii(100);
  for (double& r : radii) r = 0.5 * rng.uniform(0.1e-3, 0.15e-3);
  const double lo = 0.2 * L, hi = 0.8 * L;
  for (const PlacedSphere& p :
       random_sequential_addition(radii, {lo, hi, lo, hi, 0.0, 0.6 * L}, 4)) {
    sample.add_particle(p.position, p.radius);
  }
  sample.set_dt(0.5 * sample.automatic_dt());
  return sample;
}

inline std::vector<Check> body_checks(const SimulationConfig& cfg, const ApiFactory& api,
                                      const std::string& what, std::vector<int> moved,
                                      std::uint64_t steps = 4000) {
  const Simulation sample = body_sample(cfg);
  Simulation cpu = sample, d1 = sample, d2 = sample;
  const std::size_t builds0 = sample.neighbors().builds();
  cpu.step(steps);
  run_device(d1, steps, api);
  run_device(d2, steps, api);
  const double r = mean_radius(sample);
  const double dev = max_position_difference(cpu, d1) / r;
  double dbody = 0.0;
  for (int k = 0; k < cpu.walls().size(); ++k) {
    dbody = std::max(dbody, std::fabs(cpu.walls().position(k) - d1.walls().position(k)) / r);
  }
  int touching = 0;  // contacts with the bodies beyond the box or those that moved
  for (const ContactRecord& rec : cpu.contacts()) {
    const bool watched =
        rec.id_j >= kNumWalls || std::find(moved.begin(), moved.end(), rec.id_j) != moved.end();
    touching += rec.is_wall && watched;
  }
  const std::size_t bc = cpu.neighbors().builds() - builds0, bd = d1.neighbors().builds() - builds0;
  bool same = identical(d1, d2);
  for (int k = kNumWalls; k < d1.walls().size(); ++k) {
    same = same && d1.walls().state(k).position == d2.walls().state(k).position;
  }
  bool all_moved = true;
  std::string travel;
  for (const int k : moved) {
    const double q = cpu.walls().position(k) - sample.walls().position(k);
    all_moved = all_moved && q != 0.0;
    travel += fmt(" %.3g", q / r);
  }
  return {{dev < 1e-6 && dbody < 1e-6 && touching > 10 && all_moved,
           what + ": the device follows the CPU",
           fmt("max |dx|/r_mean = %.3g, bodies %.3g (tolerance 1e-6); %.0f grain-body contacts; "
               "moved by (r_mean)",
               dev, dbody, touching) +
               travel},
          {bc == bd && bd >= 1, what + ": the same neighbour rebuilds",
           fmt("CPU %.0f, device %.0f rebuilds", static_cast<double>(bc), static_cast<double>(bd))},
          {same, what + ": two device runs are bit-identical",
           "positions, velocities, forces, walls, bodies and clock"}};
}

/// The chamber's cylinder of body_checks' samples: radius R about the box's centre line,
/// servo-controlled to 200 kPa by its radius.
inline BodyConfig check_chamber(double R) {
  const double L = 1.25e-3, c = 0.5 * L;
  BodyConfig chamber;
  chamber.name = "chamber";
  chamber.kind = BodyKind::CylinderInside;
  chamber.origin = {c, c, -L};
  chamber.radius = R;
  chamber.length = 3.0 * L;
  chamber.motion = BodyMotion::Dilate;
  chamber.mode = WallMode::Servo;
  chamber.target_stress = 2e5;
  chamber.max_speed = 10.0;
  return chamber;
}

/// i) Bodies beyond the box and gravity: grains in a chamber whose cylinder is servo-controlled
/// by its radius, a pile with a conical tip driven into them at a prescribed velocity, and a
/// platen servo-controlled from above (body_checks).
inline SimulationConfig bodies_config() {
  const double L = 1.25e-3, c = 0.5 * L;
  SimulationConfig cfg = box_config(-L, 2.0 * L, NormalLaw::Rough);
  cfg.damping.local_alpha = 0.7;
  cfg.contact.wall_friction = 0.2;
  cfg.gravity.g = {0.0, 0.0, -9.81e3};  // strong enough to matter in 4,000 steps
  BodyConfig pile;
  pile.name = "pile";
  pile.kind = BodyKind::Pile;
  pile.origin = {c, c, 0.64 * L};
  pile.radius = 0.12e-3;
  pile.length = 2.0 * L;
  pile.friction = 0.3;
  pile.mode = WallMode::Velocity;
  pile.velocity = 10.0;
  BodyConfig platen;
  platen.name = "platen";
  platen.kind = BodyKind::Disk;
  platen.origin = {c, c, 0.62 * L};
  platen.radius = 0.6 * L;
  platen.mode = WallMode::Servo;
  platen.target_stress = 2e5;
  platen.max_speed = 10.0;
  cfg.bodies = {check_chamber(0.52 * L), pile, platen};
  return cfg;
}

inline std::vector<Check> bodies(const ApiFactory& api) {
  return body_checks(bodies_config(), api, "bodies", {kNumWalls, kNumWalls + 1});
}

/// k) The automatic time step's contact term (Simulation::stiffness_dt(), min sqrt(m / sum k)),
/// reduced on the device, is the host's on the same state bit for bit: a compressed sample
/// between the box's servo walls, and grains about curved bodies (bodies' chamber, pile and
/// platen, the pile moving), each after it has run on the device; and the automatic step a device
/// run chooses is the host's choice on the same state.
inline std::vector<Check> stiffness_time(const ApiFactory& api) {
  std::vector<Check> out;
  const auto check = [&](const std::string& what, Simulation s, std::uint64_t steps) {
    DeviceStepper d(api());
    d.advance(s, steps);
    const double on_device = d.stiffness_time();
    d.sync(s, Sync::All);
    const double on_host = s.stiffness_dt();
    int walls = 0;
    for (const ContactRecord& rec : s.contacts()) walls += rec.is_wall;
    out.push_back(
        {on_device == on_host && std::isfinite(on_host) && walls > 0,
         "time step: " + what + ": the device's stiffness time is the host's",
         fmt("device %.17g s, host %.17g s; %.0f wall contacts", on_device, on_host, walls)});
  };
  check("box", compressed_sample(0.05), 1500);
  check("bodies", body_sample(bodies_config()), 3000);
  // One grain pressed into the chamber's cylinder alone: the minimum is its curved contact's.
  const double L = 1.25e-3, r = 0.06e-3;
  Simulation one(bodies_config());
  one.add_particle({0.5 * L + 0.52 * L - 0.9 * r, 0.5 * L, 0.3 * L}, r);
  one.set_dt(0.5 * one.automatic_dt());
  check("a grain on the chamber's cylinder", one, 10);
  const double fixed = one.current_dt();
  one.choose_dt(1.0);  // a device's choice never replaces a fixed step
  out.push_back({one.current_dt() == fixed, "time step: a fixed step stays fixed",
                 fmt("%.17g s, fixed at %.17g s", one.current_dt(), fixed)});
  // The automatic step as a device run chooses it (a batch ends where it is due): at the next
  // due step, the host's choice on the same state, to the bit.
  Simulation s = compressed_sample(0.05);
  const std::uint64_t every = s.config().timestep.update_interval;
  const std::uint64_t since = s.step_count() - s.time_step().computed_at();
  DeviceStepper d(api());
  d.advance(s, every + (since < every ? every - since : 0));
  d.sync(s, Sync::All);
  const double chosen = s.current_dt(), at = static_cast<double>(s.time_step().computed_at());
  const double on_host = s.automatic_dt();
  out.push_back({chosen == on_host && at == static_cast<double>(s.step_count()),
                 "time step: the automatic step the device chose is the host's",
                 fmt("device %.17g s, host %.17g s; chosen at step %.0f of %.0f", chosen, on_host,
                     at, static_cast<double>(s.step_count()))});
  return out;
}

/// j) A chamber sample: the chamber's cylinder and the box's top wall as its platen, both
/// servo-controlled on the areas of the chamber (2 pi R H and pi R^2, walls/body_geometry.hpp
/// chamber_area) (body_checks).
inline std::vector<Check> chamber_sample(const ApiFactory& api) {
  const double L = 1.25e-3;
  SimulationConfig cfg = box_config(-L, 2.0 * L, NormalLaw::Rough);
  // Free spins here (the other checks run the default, blocked): the device path of free
  // rotation with bodies. Blocked spheres slide more, and their sliding thresholds amplify
  // round-off past this check's 1e-6 over 8,000 steps (1.1e-4 measured, spins zero on both).
  cfg.contact.rotation = Rotation::Free;
  cfg.damping.local_alpha = 0.7;
  cfg.gravity.g = {0.0, 0.0, -9.81e3};
  cfg.walls[4].position = 0.0;
  cfg.walls[5].position = 0.62 * L;
  cfg.walls[5].mode = WallMode::Servo;
  cfg.walls[5].target_stress = 2e5;
  cfg.walls[5].max_speed = 10.0;
  BodyConfig chamber = check_chamber(0.45 * L);  // clear of the grains' corners by 0.03 L
  chamber.chamber = true;
  cfg.bodies = {chamber};
  return body_checks(cfg, api, "chamber sample", {5, kNumWalls}, 8000);
}

inline std::vector<Check> all(const ApiFactory& api) {
  std::vector<Check> out;
  const auto add = [&](std::vector<Check> c) { out.insert(out.end(), c.begin(), c.end()); };
  add(impact(api));
  add(rebuild_history(api, 0.0));
  add(rebuild_history(api, 0.2));
  const Simulation sample = compressed_sample();
  Simulation fixed = sample;
  fixed.set_dt(fixed.dt());
  add(compare_runs("fixed step", fixed, 2000, api, false));
  add(compare_runs("automatic step", sample, 2000, api, false));
  Simulation moving = fixed;
  moving.walls().config(3).mode = WallMode::Velocity;  // ymax pushes in at 1 m/s
  moving.walls().config(3).velocity = -1.0;
  add(compare_runs("moving wall", moving, 2000, api, true));
  add(compare_load(fixed, 2000, api));
  add(host_changes(fixed, api));
  add(crushing(fixed, api));
  add(nan_rule(fixed, api));
  add(inspection(api));
  add(stiffness_time(api));
  add(bodies(api));
  add(chamber_sample(api));
  return out;
}

}  // namespace crushdem::device_checks
