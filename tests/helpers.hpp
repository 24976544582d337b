// Shared set-up for the C++ tests.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <random>

#include "box_config.hpp"
#include "crushdem/core/deterministic.hpp"
#include "crushdem/integrate/simulation.hpp"
#include "fixtures.hpp"

#ifdef CRUSHDEM_HAVE_OPENMP
#include <omp.h>
#endif

namespace crushdem::testing {

/// The smallest whole run configuration: 10 generated grains in a 1 mm box, 20 steps (every
/// section ends, so a test may append a table such as [contact]).
inline std::string tiny_run_toml() {
  return test_data("tiny_run.toml");
}

/// Adds an n x n x n cubic lattice of spacing a from the origin: each coordinate jittered by
/// up to jitter a, radius r0 (radius_mean + radius_spread u), velocity components up to speed
/// and spin components up to spin, with u uniform in [-1, 1] from a generator seeded with seed.
inline void add_jittered_lattice(Simulation& sim, int n, double a, std::uint64_t seed,
                                 double jitter, double r0, double radius_mean, double radius_spread,
                                 double speed, double spin) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int ix = 0; ix < n; ++ix) {
    for (int iy = 0; iy < n; ++iy) {
      for (int iz = 0; iz < n; ++iz) {
        const Vec3 x{(ix + jitter * u(rng)) * a, (iy + jitter * u(rng)) * a,
                     (iz + jitter * u(rng)) * a};
        sim.add_particle(x, r0 * (radius_mean + radius_spread * u(rng)),
                         Vec3{speed * u(rng), speed * u(rng), speed * u(rng)},
                         Vec3{spin * u(rng), spin * u(rng), spin * u(rng)});
      }
    }
  }
}

}  // namespace crushdem::testing

#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "crushdem/io/config.hpp"
#include "crushdem/io/toml.hpp"
#include "crushdem/run/runner.hpp"
#include "crushdem/run/signals.hpp"

namespace crushdem::testing {

/// Grain radius and side of the tight lattice (tight_lattice_config(), add_tight_lattice()).
inline constexpr double kTightR0 = 0.5e-3;
inline constexpr int kTightSide = 9;

/// The box, friction and damping of a 9 x 9 x 9 jittered lattice of radii 0.99 to 1.01 kTightR0
/// pressed into a box that holds it tightly (overlaps of a few um against each other and the
/// walls, about half the list's pairs touching): friction 0.3, viscous and local damping on.
/// The caller adds its own keys, builds the simulation and adds the grains (add_tight_lattice()).
inline SimulationConfig tight_lattice_config(NormalLaw law) {
  const double a = 2.0 * kTightR0;
  SimulationConfig cfg = box_config(-0.5 * a, (kTightSide - 0.5) * a, law);
  cfg.material.friction = 0.3;
  cfg.contact.restitution = 0.5;
  cfg.damping.local_alpha = 0.2;
  return cfg;
}

/// The grains of tight_lattice_config(), with random velocities and spins from `seed`.
inline void add_tight_lattice(Simulation& sim, std::uint64_t seed) {
  add_jittered_lattice(sim, kTightSide, 2.0 * kTightR0, seed, 0.003, kTightR0, 0.995, 0.01, 0.05,
                       50.0);
}

/// Sets the team size of the following parallel regions (nothing without OpenMP).
inline void set_threads(int t) {
#ifdef CRUSHDEM_HAVE_OPENMP
  omp_set_num_threads(t);
#else
  (void)t;
#endif
}

/// A test over the normal laws that may change the thread count and the threading threshold:
/// both are put back after each test.
class ThreadedLawTest : public ::testing::TestWithParam<NormalLaw> {
 protected:
  void TearDown() override {
    set_threads(saved_threads_);
    threading_threshold() = saved_threshold_;
  }
  std::size_t saved_threshold_ = threading_threshold();
#ifdef CRUSHDEM_HAVE_OPENMP
  int saved_threads_ = omp_get_max_threads();
#else
  int saved_threads_ = 1;
#endif
};

/// Every particle value and the contact count of two simulations equal, bit for bit.
inline void expect_same_state(const Simulation& a, const Simulation& b) {
  const ParticleStore &p = a.particles(), &q = b.particles();
  ASSERT_EQ(p.size(), q.size());
  EXPECT_EQ(p.id, q.id);
  // Exact equality of every value.
  EXPECT_EQ(p.x, q.x);
  EXPECT_EQ(p.y, q.y);
  EXPECT_EQ(p.z, q.z);
  EXPECT_EQ(p.vx, q.vx);
  EXPECT_EQ(p.vy, q.vy);
  EXPECT_EQ(p.vz, q.vz);
  EXPECT_EQ(p.wx, q.wx);
  EXPECT_EQ(p.wy, q.wy);
  EXPECT_EQ(p.wz, q.wz);
  EXPECT_EQ(p.tx, q.tx);
  EXPECT_EQ(a.num_contacts(), b.num_contacts());
}

/// A CSV file as columns of numbers.
inline std::map<std::string, std::vector<double>> read_csv(const std::string& path) {
  std::ifstream f(path);
  std::string line;
  std::getline(f, line);
  std::vector<std::string> names;
  {
    std::stringstream ss(line);
    std::string c;
    while (std::getline(ss, c, ',')) names.push_back(c);
  }
  std::map<std::string, std::vector<double>> cols;
  while (std::getline(f, line)) {
    std::stringstream ss(line);
    std::string c;
    for (std::size_t k = 0; k < names.size() && std::getline(ss, c, ','); ++k) {
      cols[names[k]].push_back(std::stod(c));
    }
  }
  return cols;
}

/// Runs a TOML configuration (paths relative to `base_dir`) into `out` quietly.
inline RunSummary run_toml(const std::string& text, const std::filesystem::path& out,
                           const std::filesystem::path& base_dir) {
  const RunConfig cfg =
      run_config_from_toml(toml::parse(text, "test.toml"), "test.toml", base_dir.string());
  std::filesystem::remove_all(out);
  RunOptions opt;
  opt.out_dir = out.string();
  opt.progress = false;
  return run_to_directory(cfg, opt);
}

inline std::string read_file(const std::filesystem::path& p) {
  std::ifstream f(p);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

/// Every file of run directory `a` (timing.json aside: wall-clock seconds) exists in `b` with the
/// same bytes; returns how many were compared.
inline std::size_t expect_same_run_files(const std::filesystem::path& a,
                                         const std::filesystem::path& b) {
  namespace fs = std::filesystem;
  std::size_t compared = 0;
  for (const auto& e : fs::recursive_directory_iterator(a)) {
    // Wall-clock times; the log of what happened when (a resume adds its lines).
    const auto name = e.path().filename();
    if (!e.is_regular_file() || name == "timing.json" || name == "run.log") continue;
    const fs::path other = b / fs::relative(e.path(), a);
    EXPECT_TRUE(fs::exists(other)) << other;
    EXPECT_EQ(read_file(e.path()), read_file(other)) << "differs: " << fs::relative(e.path(), a);
    ++compared;
  }
  return compared;
}

/// Runs `cfg` into `stopped` with a stop request (as SIGINT sends) as soon as the file `marker`
/// appears there (a stage's own file: the stop lands in that stage), resumes it, and expects the
/// files of `whole`, the same run uninterrupted; returns how many were compared (0: the run
/// ended before the stop).
inline std::size_t expect_stopped_run_resumes_exactly(const RunConfig& cfg, RunOptions opt,
                                                      const std::filesystem::path& whole,
                                                      const std::filesystem::path& stopped,
                                                      const std::string& marker) {
  opt.out_dir = stopped.string();
  std::atomic<bool> done{false};
  std::thread stopper([&] {
    while (!done && !std::filesystem::exists(stopped / marker)) {
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    if (!done) request_stop(SIGINT);
  });
  bool interrupted = false;
  try {
    run_to_directory(cfg, opt);
  } catch (const Interrupted&) {
    interrupted = true;
  }
  done = true;
  stopper.join();
  EXPECT_TRUE(interrupted) << "the run ended before the stop request";
  if (!interrupted) return 0;
  EXPECT_TRUE(std::filesystem::exists(stopped / "checkpoint.bin"));
  resume_directory(stopped.string(), opt);
  return expect_same_run_files(whole, stopped);
}

/// A number from a flat "key": value in a JSON text (the n-th occurrence).
inline double json_number(const std::string& json, const std::string& key, int nth = 0) {
  std::size_t at = 0;
  for (int k = 0; k <= nth; ++k) {
    at = json.find("\"" + key + "\":", at);
    if (at == std::string::npos) return std::nan("");
    at += key.size() + 3;
  }
  return std::stod(json.substr(at));
}

}  // namespace crushdem::testing
