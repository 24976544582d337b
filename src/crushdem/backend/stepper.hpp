// What advances a Simulation: the CPU engine itself, or a device copy of its state (the GPU, or
// the host emulation of the device step that tests it without a GPU). The run driver and the
// experiments see only this interface; a controller reads and changes the host Simulation
// between calls, and the stepper makes sure the two copies agree:
//
//   advance(sim, n)   n steps. Crushing, when attached, is checked every crushing.interval steps
//                     (counted from step 0) inside, and the grains that fail are split on the
//                     host (Crusher::split) and reported, as the CPU engine does between steps;
//   sync(sim, what)   the host Simulation made current (after advance(), before anything
//                     reads it): Sync::Clock brings the clock, the walls and the scalars a
//                     controller's check reads (Simulation::Inspection, reduced on the device);
//                     Sync::All every grain and contact array too. Whatever host code changes
//                     afterwards (walls, friction, grains, crack lengths, the time step)
//                     reaches the device at the next advance(); grains only after Sync::All.
//
// Backends: "cpu" (the engine, bit for bit what Simulation::step gives), "emulated" (the
// device step run by the host, serially, in the device's order of summation: the GPU's results
// bit for bit, in every build) and "cuda" (builds with -DCRUSHDEM_CUDA=ON and a GPU).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "crushdem/fracture/crushing.hpp"
#include "crushdem/integrate/simulation.hpp"

namespace crushdem {

/// Receives the grains a crushing check broke (after the split, before anything else runs).
using BreakageSink = std::function<void(const std::vector<BreakageEvent>&)>;

/// What a sync brings to the host.
enum class Sync {
  Clock,  // the clock, the walls, the crushing time and the inspection
  All,    // everything
};

class Stepper {
 public:
  virtual ~Stepper() = default;
  /// "cpu", "emulated" or "cuda".
  virtual std::string name() const = 0;
  /// From now on the crusher's check runs every crushing.interval steps inside advance(); the
  /// events of each check that breaks grains go to `sink`. Null detaches it.
  virtual void attach_crusher(Crusher* crusher, BreakageSink sink) {
    crusher_ = crusher;
    sink_ = std::move(sink);
  }
  /// Advances n steps.
  virtual void advance(Simulation& sim, std::uint64_t n) = 0;
  /// Makes the host Simulation current (`what` of it).
  virtual void sync(Simulation& sim, Sync what = Sync::All) {
    (void)sim;
    (void)what;
  }
  /// The longest call of advance() a driver should make before it looks for a stop request.
  virtual std::uint64_t max_chunk() const { return 2000; }
  /// Device memory in use [bytes] (0 for the CPU engine).
  virtual std::size_t device_bytes() const { return 0; }
  /// Grains times steps advanced so far (the count as it was at each step).
  double particle_steps() const { return particle_steps_; }

 protected:
  /// Steps to the next crushing check from step `step` (the interval when there is no crusher).
  std::uint64_t steps_to_crushing_check(std::uint64_t step) const;
  Crusher* crusher_ = nullptr;
  BreakageSink sink_;
  double particle_steps_ = 0.0;
};

/// The CPU engine: Simulation::step, with the crushing check between steps.
class CpuStepper : public Stepper {
 public:
  std::string name() const override { return "cpu"; }
  void advance(Simulation& sim, std::uint64_t n) override;
};

/// The backend names make_stepper() takes, for messages: "cpu, emulated" (and "cuda" in a build
/// with CUDA).
std::string stepper_names();
/// ConfigError naming `key` unless `backend` is a name make_stepper() takes in this build.
void check_backend_name(const std::string& backend, const std::string& key = "--backend");
/// A stepper by backend name; ConfigError naming `key` for an unknown name or one this build
/// lacks, RuntimeFailure for "cuda" without a usable GPU.
std::unique_ptr<Stepper> make_stepper(const std::string& backend,
                                      const std::string& key = "--backend");

}  // namespace crushdem
