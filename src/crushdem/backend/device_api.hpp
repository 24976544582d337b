// The device behind a DeviceStepper: its memory and its launches. Two implementations: the CUDA
// runtime with the kernels of backend/cuda_device.cu (built with -DCRUSHDEM_CUDA=ON), and the
// host emulation (backend/device_stepper.cpp), which runs the same per-thread bodies
// (backend/device_step.hpp) serially in the kernels' order of summation and so gives the
// device's bits on any machine. This header has no CUDA types.
#pragma once

#include <array>
#include <cstddef>
#include <memory>
#include <utility>

#include "crushdem/backend/device_step.hpp"
#include "crushdem/contact/contact_model.hpp"

namespace crushdem::device {

/// The contact law of a run with its table blocks where the kernels read them (device copies on
/// a GPU, the host's in the emulation). visit() calls f(ContactModel<N, C>) for the configured
/// combination: the one place a launch is instantiated per law. The kernels take the model's
/// evaluators and couple parameters; the shared parameters (friction, which a controller
/// changes) they read from the View.
struct Laws {
  ContactLaw law;
  std::array<const double*, kMaxLawTables> placed{};
  template <class F>
  decltype(auto) visit(F&& f) const {
    return with_law(law, placed.data(), std::forward<F>(f));
  }
};

class Api {
 public:
  virtual ~Api() = default;
  Api() = default;
  Api(const Api&) = delete;
  Api& operator=(const Api&) = delete;

  virtual bool emulated() const = 0;
  virtual void* allocate(std::size_t bytes) = 0;
  virtual void release(void* p) = 0;
  virtual void upload(void* device, const void* host, std::size_t bytes) = 0;
  virtual void download(void* host, const void* device, std::size_t bytes) = 0;
  /// The law with its table blocks where the kernels can read them (copied to the device on a
  /// GPU; the host's own in the emulation).
  virtual Laws place_laws(const ContactLaw& law) = 0;
  /// Runs up to `steps` whole steps; stops early when a kernel sets Control::halt (the control
  /// block says how many finished and why it stopped).
  virtual void run_steps(const View& v, const Laws& laws, int steps) = 0;
  /// The rest of a step that stopped after its drift for a rebuild: contacts, gather, clock and
  /// the crushing check.
  virtual void finish_step(const View& v, const Laws& laws) = 0;
  /// The inspection of the current state into the control block (Control::inspect_*): a first
  /// pass of blocks of kInspectBlock grains, each summed by a fixed tree, then one block summing
  /// the blocks' results by a fixed tree (the same bits on the device and the emulation).
  virtual void inspect(const View& v, const Laws& laws, unsigned grains) = 0;
  /// The stiffness time of the current state (the automatic time step's contact term, a minimum
  /// over the grains of stiffness_time_item()) into Control::stiffness_bits.
  virtual void stiffness_time(const View& v, const Laws& laws, unsigned grains) = 0;
  /// The view's pointers or parameters changed (a captured graph is stale).
  virtual void view_changed() {}
  /// Waits for the device and copies the control block to `host`.
  virtual void read_control(const View& v, Control& host) = 0;
};

/// The host emulation.
std::unique_ptr<Api> make_emulated_api();
/// The CUDA runtime; RuntimeFailure without a usable device or in a build without CUDA.
std::unique_ptr<Api> make_cuda_api();
/// Whether this build has CUDA and a device can be used.
bool cuda_available();
/// Whether this build was made with CUDA (-DCRUSHDEM_CUDA=ON).
bool cuda_built();

}  // namespace crushdem::device
