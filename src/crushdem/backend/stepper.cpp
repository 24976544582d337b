#include "crushdem/backend/stepper.hpp"

#include <algorithm>

#include "crushdem/backend/device_stepper.hpp"
#include "crushdem/core/error.hpp"

namespace crushdem {

std::uint64_t Stepper::steps_to_crushing_check(std::uint64_t step) const {
  const std::uint64_t k = crusher_ ? crusher_->config().interval : 0;
  if (k == 0) return ~std::uint64_t{0};
  return k - step % k;
}

void CpuStepper::advance(Simulation& sim, std::uint64_t n) {
  while (n > 0) {
    const std::uint64_t chunk = std::min(n, steps_to_crushing_check(sim.step_count()));
    sim.step(chunk);
    particle_steps_ += static_cast<double>(chunk) * static_cast<double>(sim.particles().size());
    n -= chunk;
    if (crusher_ && sim.step_count() % crusher_->config().interval == 0) {
      const std::vector<BreakageEvent> events = crusher_->apply(sim);
      if (events.empty()) continue;
      if (sink_) sink_(events);
      // What comes next reads forces: evaluate them for the new grains (what the next step would
      // do first anyway, with no tangential increment).
      sim.compute_forces();
    }
  }
}

std::string stepper_names() {
  return device::cuda_built() ? "cpu, emulated or cuda" : "cpu or emulated";
}

void check_backend_name(const std::string& backend, const std::string& key) {
  if (backend == "cpu" || backend == "emulated" || (backend == "cuda" && device::cuda_built())) {
    return;
  }
  if (backend == "cuda") {
    throw ConfigError(bad_value(key, backend,
                                "cpu or emulated (this crushdem was built without CUDA: "
                                "configure with -DCRUSHDEM_CUDA=ON for cuda)"));
  }
  throw ConfigError(bad_value(key, backend, stepper_names()));
}

std::unique_ptr<Stepper> make_stepper(const std::string& backend, const std::string& key) {
  check_backend_name(backend, key);
  if (backend == "cpu") return std::make_unique<CpuStepper>();
  if (backend == "emulated") return std::make_unique<DeviceStepper>(device::make_emulated_api());
  return std::make_unique<DeviceStepper>(device::make_cuda_api());
}

}  // namespace crushdem
