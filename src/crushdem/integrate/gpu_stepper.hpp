// The CUDA time-stepper: the same step as Simulation::step() (see simulation.hpp and
// ARCHITECTURE.md), run on one GPU.
//
// The constructor uploads the Simulation's state (particles, the half neighbour list with a
// reverse index built here, per-entry constants, tangential history, wall contacts, walls and
// the contact parameters); step() then advances it on the device with a fixed time step
// (Simulation::dt() at construction). One thread per neighbour entry computes the contact and
// keeps a per-entry reaction record; one thread per particle then sums its own entries, the
// entries where it is the partner (in increasing entry order) and its wall entries, so every
// floating-point sum has an order fixed by the lists: results are identical run to run. They
// are not bit-identical to the CPU step, whose sums run in column order.
//
// Neighbour rebuilds (same criterion as the CPU) are done on the host by the Simulation itself,
// which carries the tangential history by particle ids: the state is downloaded, rebuilt and
// uploaded again. download() copies the device state back into the Simulation so that it can be
// inspected or written; a Simulation changed from outside needs a new GpuStepper. When the
// Simulation tracks the contact load (track_contact_load, for crushing), the device keeps it
// too and download() fills contact_load().
//
// This header has no CUDA types and compiles without CUDA; the implementation is
// gpu_stepper.cu, built only with -DCRUSHDEM_CUDA=ON (library crushdem_cuda).
#pragma once

#include <cstdint>
#include <memory>

namespace crushdem {

class Simulation;

class GpuStepper {
 public:
  /// Device: the CUDA kernels. HostEmulation: the kernels' per-thread bodies run serially on the
  /// host in the same order of summation, giving the same bits as the device (for tests, and to
  /// check the logic on a machine without a GPU).
  enum class Mode { Device, HostEmulation };

  /// Brings `sim` up to date (forces, neighbour list) and uploads it. `sim` must outlive this.
  explicit GpuStepper(Simulation& sim, Mode mode = Mode::Device);
  ~GpuStepper();
  GpuStepper(const GpuStepper&) = delete;
  GpuStepper& operator=(const GpuStepper&) = delete;

  /// Advances n steps; returns after the device has finished them.
  void step(std::uint64_t n);
  /// Copies the device state back into the Simulation (particles, contact history, walls).
  void download();
  /// True when a CUDA device can be used.
  static bool available();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace crushdem
