// `crushdem-sand bench`: the peer reference problem (bench/README.md).
//
// Loads the reference packing (11,500 spheres in a box of 6 walls at 5 MPa) or a prepared sample
// (a chamber sample with its chamber and symmetry planes, fixed), runs WARM untimed
// then STEPS timed steps with the same contact law and constants as the peers (Hertz-Mindlin,
// Coulomb, Tsuji viscous damping from the restitution REST, walls with the same friction), and
// prints particle_steps_per_s=<N*STEPS/seconds> as the last line. Values come from the command
// line, else from the environment variables the peer harness sets (CLI11's envname for the
// options, env_number for the constants), else from its lib.sh defaults.
// --backend cuda runs the warm-up and the timed steps on the GPU (DeviceStepper, builds with
// -DCRUSHDEM_CUDA=ON only; --backend emulated runs its step on the host); the clock stops after
// the device has finished.
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "crushdem/backend/stepper.hpp"
#include "crushdem/cli/cli.hpp"
#include "crushdem/core/error.hpp"
#include "crushdem/core/part_clock.hpp"
#include "crushdem/core/state_io.hpp"
#include "crushdem/experiments/protocol.hpp"
#include "crushdem/integrate/simulation.hpp"
#include "crushdem/io/config.hpp"
#include "crushdem/io/output.hpp"
#include "crushdem/io/packing.hpp"
#include "crushdem/run/runner.hpp"

#ifdef CRUSHDEM_HAVE_OPENMP
#include <omp.h>
#endif

namespace crushdem::cli {
namespace {

double env_number(const char* name, double fallback) {
  const char* v = std::getenv(name);
  if (!v || !*v) return fallback;
  char* end = nullptr;
  const double x = std::strtod(v, &end);
  if (end == v || *end != '\0' || !std::isfinite(x)) {
    throw ConfigError(std::string("environment variable ") + name + "=" + v +
                      ": expected a number");
  }
  return x;
}

/// The peer problem's constants (bench/peers/common/lib.sh), from the environment variables its
/// harness sets, else their defaults there.
void set_peer_constants(SimulationConfig& cfg, const std::string& law) {
  cfg.material.density = env_number("RHO", 2650.0);
  cfg.material.shear_modulus = env_number("G_SHEAR", 32e9);
  cfg.material.poisson_ratio = env_number("NU", 0.19);
  cfg.material.friction = env_number("MU", 0.275);
  cfg.contact.law = parse_normal_law(law, "--law");
  cfg.contact.wall_friction = cfg.material.friction;
  cfg.contact.restitution = env_number("REST", 0.5);
  cfg.contact.rotation = Rotation::Free;  // the peers' spheres turn freely
  cfg.damping.local_alpha = 0.0;          // the peers use viscous contact damping only
  cfg.timestep.dt = env_number("DT", 1.494169e-8);
  cfg.neighbor.skin = env_number("SKIN", 3.75e-5);
}

long peak_rss_kib() {
  std::ifstream s("/proc/self/status");
  std::string line;
  while (std::getline(s, line)) {
    if (line.rfind("VmHWM:", 0) == 0) return std::strtol(line.c_str() + 6, nullptr, 10);
  }
  return -1;
}

/// First line of a --settled-state file: what the state was settled from and how (the law, the
/// settle length, the packing's bytes by their FNV-1a hash, and the constants the environment
/// can change), so that a file from another run is refused rather than timed.
std::string settled_state_header(const std::string& law, long settle,
                                 const std::string& packing_path, const SimulationConfig& cfg) {
  const std::string packing = read_binary_file(packing_path);
  const std::uint64_t hash = fnv1a64(packing.data(), packing.size());
  char text[512];
  std::snprintf(text, sizeof text,
                "crushdem-bench-settled v%d law=%s settle=%ld packing_fnv1a=%016llx rho=%.17g "
                "G=%.17g nu=%.17g mu=%.17g rest=%.17g dt=%.17g skin=%.17g\n",
                kStateVersion, law.c_str(), settle, static_cast<unsigned long long>(hash),
                cfg.material.density, cfg.material.shear_modulus, cfg.material.poisson_ratio,
                cfg.material.friction, cfg.contact.restitution, cfg.timestep.dt, cfg.neighbor.skin);
  return text;
}

}  // namespace

int bench_main(const BenchArgs& a) {
  // --run DIR: the run's prepared sample with the run's own configuration.
  const bool from_run = !a.run.empty();
  if (!from_run && a.packing.empty()) {
    throw ConfigError("give --packing FILE (or the PACKING variable) or --run DIR");
  }
  if (from_run && a.law_given) {
    throw ConfigError(
        bad_value("--law", a.law, "no --law with --run (the run's config.toml gives the law)"));
  }
  if (from_run && a.settle > 0) {
    throw ConfigError(bad_value("--settle", std::to_string(a.settle),
                                "0 with --run (the sample is timed as the run prepared it)"));
  }
  const std::filesystem::path run_dir(a.run);
  if (from_run && !(std::filesystem::is_regular_file(run_dir / "config.toml") &&
                    std::filesystem::is_regular_file(run_dir / "sample.txt"))) {
    throw ConfigError(bad_value("--run", "\"" + a.run + "\"",
                                "a run directory whose preparation has finished (config.toml and "
                                "sample.txt)"));
  }
  const std::string packing_path = from_run ? (run_dir / "sample.txt").string() : a.packing;
  const long steps = a.steps, warm = a.warm, settle = a.settle, prune = a.prune;
  const std::string &state_out = a.state_out, &backend = a.backend;
  const std::string& settled_state = a.settled_state;
  if (prune != 0 && prune != 1) {
    throw ConfigError(bad_value("--prune", std::to_string(prune), "0 (walk the full list) or 1"));
  }
  check_backend_name(backend);
  if (steps <= 0)
    throw ConfigError(bad_value("--steps", std::to_string(steps), "a positive count"));
  if (warm < 0) throw ConfigError(bad_value("--warm", std::to_string(warm), "a count >= 0"));
  if (settle < 0) {
    throw ConfigError(bad_value("--settle", std::to_string(settle), "a count >= 0"));
  }
  if (!settled_state.empty() && settle == 0) {
    throw ConfigError(
        "--settled-state '" + settled_state +
        "': needs --settle N (the state it caches is the one after N settling steps)");
  }
  set_threads(a.threads);

  if (!std::ifstream(packing_path) && std::ifstream(packing_path + ".gz")) {
    throw ConfigError("--packing '" + packing_path + "' does not exist, but '" + packing_path +
                      ".gz' does: unpack it first (gunzip -k '" + packing_path + ".gz')");
  }
  const Packing pk = read_packing(packing_path);
  // The reference packing is a cube [0, L]^3 ('# L_m='); a prepared sample (`# box_xmin=` ...,
  // as `crushdem-sand run` writes for a [sample]) carries its six wall positions.
  std::array<double, kNumWalls> wall_position{};
  if (pk.has_box()) {
    wall_position = pk.box(packing_path);
  } else {
    const double L = pk.header_number("L_m", packing_path);
    for (int k = 0; k < kNumWalls; ++k) {
      wall_position[static_cast<std::size_t>(k)] = wall_is_low(k) ? 0.0 : L;
    }
  }

  SimulationConfig cfg;
  if (from_run) {
    cfg = upscaled(load_saved_run_config((run_dir / "config.toml").string())).simulation;
  } else {
    set_peer_constants(cfg, a.law);
  }
  cfg.neighbor.prune = prune != 0;
  for (int k = 0; k < kNumWalls; ++k) {
    cfg.walls[static_cast<std::size_t>(k)] = WallConfig{};  // fixed
    cfg.walls[static_cast<std::size_t>(k)].position = wall_position[static_cast<std::size_t>(k)];
  }
  const std::string law = to_string(cfg.contact.law);
  // A chamber sample (as `crushdem-sand run` writes one): its chamber and symmetry planes, fixed
  // where the file has them, so that its grains stay confined and the bodies' share is timed.
  const Packing::Chamber chamber = pk.chamber(packing_path, from_run ? "--run" : "--packing");
  if (chamber.radius > 0.0) {
    for (const BodyConfig& b :
         file_chamber_bodies(chamber.radius, chamber.sector, wall_position[4], wall_position[5])) {
      cfg.bodies.push_back(b);
    }
  }
  Simulation sim(cfg);
  add_packing_particles(sim, pk);
  const auto N = static_cast<double>(sim.particles().size());
  if (settle > 0) {
    // --settle N: the reference packing is at rest under smooth Hertz only. Under the rough law
    // the same overlaps carry far less force, so the box unloads (to about 0.07 MPa) and a third
    // of the contacts slide: that times another state, not the law. Settling first gives the
    // law its own state at rest, contact history included (a file cannot carry it): N steps with
    // the six walls servo-controlled to the packing's stress and local damping, then the state
    // moved into the benchmark's simulation (no local damping) with its walls (fixed).
    const double stress = pk.header_number("p_target_Pa", packing_path);
    SimulationConfig sc = cfg;
    sc.damping.local_alpha = 0.7;
    for (auto& w : sc.walls) {
      w.mode = WallMode::Servo;
      w.target_stress = stress;
    }
    // --settled-state FILE: the settled state is kept in FILE (written after settling when FILE
    // does not exist, read instead of settling when it does), so that repeated timings of a
    // long settle pay for it once. The settle is deterministic and thread-count independent,
    // so the file holds the state this run would reach; its header must match this run.
    const std::string header =
        settled_state.empty() ? "" : settled_state_header(law, settle, packing_path, cfg);
    std::string bytes;
    if (!settled_state.empty() && std::ifstream(settled_state)) {
      bytes = read_binary_file(settled_state);
      if (bytes.compare(0, header.size(), header) != 0) {
        throw ConfigError("--settled-state '" + settled_state + "': it was written for another " +
                          "run (expected the header '" + header.substr(0, header.size() - 1) +
                          "'); delete it to settle again");
      }
      bytes.erase(0, header.size());
    } else {
      Simulation settler(sc);
      add_packing_particles(settler, pk);
      settler.step(static_cast<std::uint64_t>(settle));
      StateWriter state;
      save_state(settler, state);
      bytes = state.bytes();
      if (!settled_state.empty()) write_file_atomically(settled_state, header + bytes);
    }
    StateReader in(std::move(bytes), "the settled state");
    load_state(sim, in);
    double p = 0.0;
    for (int k = 0; k < kNumWalls; ++k) {
      sim.walls().config(k) = cfg.walls[static_cast<std::size_t>(k)];
      sim.walls().state(k).velocity = 0.0;
      p += sim.walls().stress(k) / kNumWalls;
    }
    std::printf("settled steps=%ld target_Pa=%.6e p_wall_Pa=%.6e ke_J=%.6e\n", settle, stress, p,
                sim.kinetic_energy());
  }

  const std::unique_ptr<Stepper> stepper = make_stepper(backend);
  const auto advance = [&](long n) { stepper->advance(sim, static_cast<std::uint64_t>(n)); };
  advance(warm);
  stepper->sync(sim);
  sim.compute_forces();
  const std::size_t builds0 = sim.neighbors().builds();
  const std::size_t prunes0 = sim.pruned_neighbors().builds();
  const auto parts0 = sim.part_clock().seconds();
  const auto t0 = std::chrono::steady_clock::now();
  advance(steps);  // returns when the device has finished
  const auto t1 = std::chrono::steady_clock::now();
  const auto parts1 = sim.part_clock().seconds();
  stepper->sync(sim);
  const double secs = std::chrono::duration<double>(t1 - t0).count();

  // The boundary's mean stress as a run measures it (mean_stress_Pa): in a chamber the cylinder
  // stands for both lateral axes, and the unused x and y box walls do not count.
  const auto& walls = sim.walls();
  const double p_wall = walls.mean_stress();
  const auto s = sim.love_weber_stress();
  std::printf("N=%.0f steps=%ld warm=%ld threads=%d law=%s dt_s=%.6e skin_m=%.6e backend=%s\n", N,
              steps, warm, current_threads(), law.c_str(), sim.dt(), sim.skin(), backend.c_str());
  std::printf("neighbor_pairs=%zu contacts=%zu neigh_builds_timed=%zu\n",
              sim.neighbors().num_pairs(), sim.num_contacts(), sim.neighbors().builds() - builds0);
  std::printf("pruned_pairs=%zu inner_skin_m=%.3e prune_builds_timed=%zu\n",
              sim.pruned_neighbors().size(), sim.pruned_neighbors().inner_skin(),
              sim.pruned_neighbors().builds() - prunes0);
  std::printf("p_wall_Pa=%.6e p_love_Pa=%.6e ke_J=%.6e\n", p_wall, (s[0] + s[4] + s[8]) / 3.0,
              sim.kinetic_energy());
  // The timed steps' seconds by part (a device's whole step is contact_forces) and the bodies.
  std::printf("bodies=%zu chamber_radius_m=%.6e sector_deg=%g\n", cfg.bodies.size(), chamber.radius,
              chamber.sector);
  std::printf("timed_seconds");
  for (std::size_t k = 0; k < PartClock::kParts; ++k) {
    std::printf(" %.*s=%.4f", static_cast<int>(kPartNames[k].size()), kPartNames[k].data(),
                parts1[k] - parts0[k]);
  }
  std::printf("\n");
  std::printf(
      "engine_bytes_per_particle=%.0f device_bytes_per_particle=%.0f peak_rss_kib=%ld "
      "wall_s=%.4f\n",
      static_cast<double>(sim.memory_bytes()) / N, static_cast<double>(stepper->device_bytes()) / N,
      peak_rss_kib(), secs);
  if (!state_out.empty()) {
    Packing out;
    const auto& p = sim.particles();
    for (std::size_t i = 0; i < p.size(); ++i) {
      out.rows.push_back({p.id[i], {p.x[i], p.y[i], p.z[i]}, 2.0 * p.radius[i]});
    }
    write_packing(state_out, out);
  }
  std::printf("particle_steps_per_s=%.6e\n", N * static_cast<double>(steps) / secs);
  return 0;
}

}  // namespace crushdem::cli
