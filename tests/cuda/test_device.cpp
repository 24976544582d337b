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
    if (!emulate) compare_with_emulation();
  } catch (const std::exception& e) {
    report({{false, "exception", e.what()}});
  }
  std::printf("%d passed, %d failed\n", passed, failed);
  return failed == 0 ? 0 : 1;
}
