// A Stepper whose state lives on a device (backend/device_api.hpp): the GPU, or the host
// emulation of the device step.
//
// Ownership (the explicit mirrors of Cabana, HOOMD's access modes): after advance() the device
// copy is the newer one; sync() downloads it into the host Simulation: Sync::Clock the control
// block (clock, walls) and the inspection the device reduces for the controllers' checks
// (Simulation::Inspection), Sync::All every field too. Before the next advance()
// the stepper compares the host copy with what it last uploaded or downloaded, field by field
// (the transfer lists below are the one list of what the device holds), and uploads only what
// host code changed in between: a controller's wall modes and targets, the friction, the time
// step, crack lengths after an ageing jump, positions set from Python. A change of the layout
// (topology, neighbour rebuild, a loaded checkpoint: Simulation::layout_version) uploads
// everything again. Nothing is left for the caller to flag.
//
// The host keeps the jobs that change the layout: neighbour rebuilds (when the device's drift
// finds one due, it stops; the host rebuilds with the history carried over and uploads), the
// split of a grain that the device's crushing check found failing (Crusher::split, then the
// forces of the new state, as the CPU driver does). The automatic time step is chosen every
// timestep.update_interval steps from the contact term the device reduces (the host's
// stiffness_time(), bit for bit) and the Rayleigh term of the grains the host holds: no grain
// comes back for it.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "crushdem/backend/device_api.hpp"
#include "crushdem/backend/stepper.hpp"

namespace crushdem {

class DeviceStepper : public Stepper {
 public:
  explicit DeviceStepper(std::unique_ptr<device::Api> api);
  ~DeviceStepper() override;

  std::string name() const override;
  void attach_crusher(Crusher* crusher, BreakageSink sink) override;
  void advance(Simulation& sim, std::uint64_t n) override;
  void sync(Simulation& sim, Sync what = Sync::All) override;
  std::size_t device_bytes() const override;
  /// Uploads in full made so far (the first, layout changes), and smaller uploads of changed
  /// fields (for tests and reports).
  std::uint64_t full_uploads() const;
  std::uint64_t field_uploads() const;
  /// The stiffness time (the automatic time step's contact term, Simulation::stiffness_dt())
  /// of the device's copy as the last advance() left it, reduced on the device; for tests and
  /// reports.
  double stiffness_time();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace crushdem
