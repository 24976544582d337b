// The device step on the GPU (--backend cuda) against the CPU engine, and against its host
// emulation bit for bit (plain executable: no GoogleTest on the GPU machine). The checks are
// those the default suite runs on the emulation (tests/device_checks.hpp). Prints "N passed, M
// failed" as its last line; exit code 0 only when all pass. --emulate runs the checks on the
// emulation only (no GPU needed).
#include <cstdio>
#include <cstring>
#include <exception>

#include "../device_checks.hpp"

using namespace crushdem;
using device_checks::Check;

namespace {

int passed = 0, failed = 0;

void report(const std::vector<Check>& checks) {
  for (const Check& c : checks) {
    std::printf("%s %s: %s\n", c.ok ? "PASS" : "FAIL", c.name.c_str(), c.detail.c_str());
    (c.ok ? passed : failed)++;
  }
}

/// The same runs on the GPU and on the emulation give the same bits.
void compare_with_emulation() {
  Simulation sample = device_checks::compressed_sample();
  sample.track_contact_load(1.0);
  for (const bool moving : {false, true}) {
    Simulation g = sample, e = sample;
    if (moving) {
      for (Simulation* s : {&g, &e}) {
        s->walls().config(3).mode = WallMode::Velocity;
        s->walls().config(3).velocity = -1.0;
      }
    }
    device_checks::run_device(g, 3000, [] { return device::make_cuda_api(); });
    device_checks::run_device(e, 3000, [] { return device::make_emulated_api(); });
    const ContactLoad &Lg = g.contact_load(), &Le = e.contact_load();
    const bool same = device_checks::identical(g, e) &&
                      device_checks::same_bits(Lg.sigma, Le.sigma) &&
                      device_checks::same_bits(Lg.F_n_max, Le.F_n_max);
    report({{same,
             moving ? "GPU equals the emulation bit for bit (moving wall)"
                    : "GPU equals the emulation bit for bit",
             "3,000 steps with automatic dt: grains, motion, forces, walls, clock, contact load"}});
  }
}

/// Crushing on the GPU and on the emulation from one state: the same grains break at the same
/// steps and the states stay bit-identical. Instant failures only: crack growth calls pow(),
/// which CUDA rounds differently from the host (docs/performance.md, "Backends").
void compare_crushing_with_emulation() {
  Simulation sample = device_checks::compressed_sample();
  sample.set_dt(sample.dt());
  CrushingConfig cc;
  cc.enabled = true;
  cc.sigma_lim0 = 1.4e9;
  const auto run = [&](device_checks::ApiFactory api, std::vector<BreakageEvent>& events) {
    Simulation s = sample;
    for (int k = 0; k < kNumWalls; ++k) s.walls().config(k).target_stress = 3e6;
    Crusher crusher(cc, SplitPattern::default14());
    crusher.begin(s);
    DeviceStepper d(api());
    d.attach_crusher(&crusher, [&](const std::vector<BreakageEvent>& e) {
      events.insert(events.end(), e.begin(), e.end());
    });
    d.advance(s, 1500);
    d.sync(s);
    return s;
  };
  std::vector<BreakageEvent> eg, ee;
  const Simulation g = run(device::make_cuda_api, eg);
  const Simulation e = run(device::make_emulated_api, ee);
  bool same = eg.size() == ee.size() && !eg.empty();
  for (std::size_t k = 0; same && k < eg.size(); ++k) {
    same = eg[k].id == ee[k].id && eg[k].step == ee[k].step;
  }
  report({{same && device_checks::identical(g, e),
           "crushing: the GPU breaks the grains the emulation breaks, bit for bit",
           device_checks::fmt("%.0f breakages on the GPU, %.0f on the emulation",
                              static_cast<double>(eg.size()), static_cast<double>(ee.size()))}});
}

}  // namespace

int main(int argc, char** argv) {
  const bool emulate = argc > 1 && std::strcmp(argv[1], "--emulate") == 0;
  if (!emulate && !device::cuda_available()) {
    std::printf("no CUDA device (run with --emulate to check the logic on the host)\n");
    std::printf("0 passed, 1 failed\n");
    return 1;
  }
  std::printf("device: %s\n", emulate ? "host emulation" : "CUDA");
  try {
    report(device_checks::all(emulate ? device_checks::ApiFactory(device::make_emulated_api)
                                      : device_checks::ApiFactory(device::make_cuda_api)));
    if (!emulate) {
      compare_with_emulation();
      compare_crushing_with_emulation();
    }
  } catch (const std::exception& e) {
    report({{false, "exception", e.what()}});
  }
  std::printf("%d passed, %d failed\n", passed, failed);
  return failed == 0 ? 0 : 1;
}
