// The CUDA device behind a DeviceStepper (backend/device_api.hpp): device memory, the step's
// kernels over the per-thread bodies of backend/device_step.hpp, and batches of steps launched
// as one CUDA graph. Built only with -DCRUSHDEM_CUDA=ON, with -fmad=false so that each contact's
// arithmetic is the host's; the host emulation (device_stepper.cpp) runs the same bodies in the
// same order of summation and so gives these kernels' bits.
//
//   k_kick_drift  per grain; block maxima of the squared displacement, then an integer atomicMax
//                 on the bits of a non-negative double (a maximum is exact, so the order does not
//                 matter); the last block (atomic ticket) moves the walls and applies the
//                 rebuild rule;
//   k_contacts    one thread per neighbour entry, then one per wall entry;
//   k_gather      one thread per grain; six more blocks make the wall totals in a fixed tree and
//                 set the servo velocities; thread 0 advances the clock;
//   k_crushing    at a crushing step, one thread per grain (the check and crack growth).
// On demand, between batches: k_inspect_* (the controllers' scalars in fixed trees) and
// k_stiffness_time (the automatic time step's contact term, a minimum by integer atomicMin).
// Every kernel returns at once when `halt` is set, so the host finds the state where it stopped.
#include <cuda_runtime.h>

#include <limits>
#include <string>
#include <vector>

#include "crushdem/backend/device_api.hpp"
#include "crushdem/core/error.hpp"

namespace crushdem::device {
namespace {

constexpr int kGraphSteps = kBatchSteps;  // steps per CUDA graph launch

void check_cuda(cudaError_t e, const char* what, int line) {
  if (e != cudaSuccess) {
    throw RuntimeFailure(std::string("CUDA error: ") + cudaGetErrorString(e) + " in " + what +
                         " (cuda_device.cu:" + std::to_string(line) + ")");
  }
}
#define CD_CUDA(x) check_cuda((x), #x, __LINE__)

int grid(std::size_t n, int block = kBlock) {
  return static_cast<int>((n + static_cast<std::size_t>(block) - 1) /
                          static_cast<std::size_t>(block));
}

__global__ void k_kick_drift(View v) {
  __shared__ double sm[kBlock];
  Control* c = v.ctrl;
  // The same for every thread: only the last block writes it, after all blocks have read it.
  if (c->halt) return;
  const Index i = blockIdx.x * blockDim.x + threadIdx.x;
  sm[threadIdx.x] = i < c->N ? kick_drift_item(v, i) : 0.0;
  __syncthreads();
  for (int s = kBlock / 2; s > 0; s >>= 1) {
    if (static_cast<int>(threadIdx.x) < s) {
      // Not fmax: a NaN must win (kick_drift_item already made it infinite; this keeps it so).
      const double a = sm[threadIdx.x], b = sm[threadIdx.x + s];
      sm[threadIdx.x] = a < b ? b : a;
    }
    __syncthreads();
  }
  if (threadIdx.x == 0) {
    atomicMax(&c->m2_bits, static_cast<unsigned long long>(__double_as_longlong(sm[0])));
    __threadfence();
    if (atomicAdd(&c->blocks_done, 1u) == gridDim.x - 1) {
      // The last block: every block's maximum is in m2_bits.
      const unsigned long long m2 = atomicExch(&c->m2_bits, 0ull);
      c->blocks_done = 0;
      finish_drift(v, __longlong_as_double(static_cast<long long>(m2)));
    }
  }
}

// One kernel per combination of the contact law's sub-models (Laws::visit()).
template <class Model>
__global__ void k_contacts(View v, Model model) {
  if (v.ctrl->halt) return;
  const Index t = blockIdx.x * blockDim.x + threadIdx.x;
  const Index M = v.ctrl->M;
  if (t < M) {
    pair_item(v, model, t);
  } else if (t - M < v.ctrl->Mw) {
    wall_item(v, model, t - M);
  }
}

// Blocks below particle_blocks gather; the next v.bodies blocks make the body totals (they read
// only the wall entries and write only the walls, which the gather does not read).
__global__ void k_gather(View v, unsigned particle_blocks) {
  __shared__ WallSum sm[kWallThreads];
  if (v.ctrl->halt) return;
  if (blockIdx.x >= particle_blocks) {
    const int k = static_cast<int>(blockIdx.x - particle_blocks), t = threadIdx.x;
    sm[t] = wall_partial(v, k, t);
    __syncthreads();
    for (int s = kWallThreads / 2; s > 0; s >>= 1) {
      if (t < s) add_sum(sm[t], sm[t + s]);
      __syncthreads();
    }
    if (t == 0) wall_store_and_servo(v, k, sm[0]);
    return;
  }
  const Index j = blockIdx.x * blockDim.x + threadIdx.x;
  if (j < v.ctrl->N) gather_item(v, j);
  if (j == 0) advance_clock(v);
}

// Every grain is checked (crack growth applied, its flag written) even when another fails:
// the kernel counts failures and leaves `halt` to k_crushing_halt, so no thread of it can see a
// halt set by another.
__global__ void k_crushing(View v) {
  if (v.ctrl->halt || !v.fail || !crushing_step(v)) return;
  const Index i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < v.ctrl->N && crushing_item(v, i)) atomicAdd(&v.ctrl->failures, 1u);
}

__global__ void k_crushing_halt(View v) {
  if (!v.ctrl->halt && v.ctrl->failures > 0) v.ctrl->halt = kFailure;
}

template <class Model>
__global__ void k_inspect_blocks(View v, Model model, unsigned grains) {
  __shared__ InspectSum sm[kInspectBlock];
  const unsigned i = blockIdx.x * kInspectBlock + threadIdx.x;
  sm[threadIdx.x] = i < grains ? inspect_item(v, model, i) : InspectSum{0.0, 0.0, 0.0};
  __syncthreads();
  for (int s = kInspectBlock / 2; s > 0; s >>= 1) {
    if (static_cast<int>(threadIdx.x) < s) add_inspect(sm[threadIdx.x], sm[threadIdx.x + s]);
    __syncthreads();
  }
  if (threadIdx.x == 0) v.inspect_partial[blockIdx.x] = sm[0];
}

__global__ void k_inspect_total(View v, unsigned blocks) {
  __shared__ InspectSum sm[kInspectBlock];
  InspectSum acc{0.0, 0.0, 0.0};
  for (unsigned k = threadIdx.x; k < blocks; k += kInspectBlock)
    add_inspect(acc, v.inspect_partial[k]);
  sm[threadIdx.x] = acc;
  __syncthreads();
  for (int s = kInspectBlock / 2; s > 0; s >>= 1) {
    if (static_cast<int>(threadIdx.x) < s) add_inspect(sm[threadIdx.x], sm[threadIdx.x + s]);
    __syncthreads();
  }
  if (threadIdx.x == 0) {
    v.ctrl->inspect_resultant = sm[0].resultant;
    v.ctrl->inspect_F_n = sm[0].F_n;
    v.ctrl->inspect_pairs = sm[0].pairs;
  }
}

__global__ void k_stiffness_reset(View v) {
  v.ctrl->stiffness_bits = static_cast<unsigned long long>(
      __double_as_longlong(std::numeric_limits<double>::infinity()));
}

// Block minima, then an integer atomicMin of their bits (positive doubles order as their bits):
// a minimum, so the result does not depend on the order.
template <class Model>
__global__ void k_stiffness_time(View v, Model model, unsigned grains) {
  __shared__ double sm[kBlock];
  const unsigned j = blockIdx.x * kBlock + threadIdx.x;
  sm[threadIdx.x] =
      j < grains ? stiffness_time_item(v, model, j) : std::numeric_limits<double>::infinity();
  __syncthreads();
  for (int s = kBlock / 2; s > 0; s >>= 1) {
    if (static_cast<int>(threadIdx.x) < s) {
      sm[threadIdx.x] = fmin(sm[threadIdx.x], sm[threadIdx.x + s]);
    }
    __syncthreads();
  }
  if (threadIdx.x == 0) {
    atomicMin(&v.ctrl->stiffness_bits,
              static_cast<unsigned long long>(__double_as_longlong(sm[0])));
  }
}

class CudaApi : public Api {
 public:
  CudaApi() {
    if (!cuda_available()) throw RuntimeFailure("--backend cuda: no CUDA device found");
    CD_CUDA(cudaStreamCreateWithFlags(&stream_, cudaStreamNonBlocking));
  }
  ~CudaApi() override {
    if (graph_) cudaGraphExecDestroy(graph_);
    for (void* t : tables_) cudaFree(t);
    if (stream_) cudaStreamDestroy(stream_);
  }
  bool emulated() const override { return false; }
  void* allocate(std::size_t bytes) override {
    void* p = nullptr;
    CD_CUDA(cudaMalloc(&p, bytes));
    return p;
  }
  void release(void* p) override { cudaFree(p); }
  void upload(void* dev, const void* host, std::size_t bytes) override {
    if (bytes) CD_CUDA(cudaMemcpyAsync(dev, host, bytes, cudaMemcpyHostToDevice, stream_));
    CD_CUDA(cudaStreamSynchronize(stream_));
  }
  void download(void* host, const void* dev, std::size_t bytes) override {
    if (bytes) CD_CUDA(cudaMemcpyAsync(host, dev, bytes, cudaMemcpyDeviceToHost, stream_));
    CD_CUDA(cudaStreamSynchronize(stream_));
  }
  Laws place_laws(const ContactLaw& law) override {
    // Each table block the law's evaluators read, copied whole (a block may hold several
    // tables that the kernel picks by an offset).
    Laws d{law, {}};
    for (std::size_t k = 0; k < law.tables().size(); ++k) {
      const TableBlock& b = law.tables()[k];
      double* t = static_cast<double*>(allocate(b.count * sizeof(double)));
      upload(t, b.host, b.count * sizeof(double));
      tables_.push_back(t);
      d.placed[k] = t;
    }
    return d;
  }
  void view_changed() override { graph_stale_ = true; }
  void run_steps(const View& v, const Laws& laws, int steps) override {
    if (steps == kGraphSteps) {
      if (graph_stale_) capture(v, laws);
      CD_CUDA(cudaGraphLaunch(graph_, stream_));
    } else {
      for (int s = 0; s < steps; ++s) launch_step(v, laws);
    }
    CD_CUDA(cudaGetLastError());
  }
  void finish_step(const View& v, const Laws& laws) override {
    launch_forces(v, laws);
    CD_CUDA(cudaGetLastError());
  }
  void inspect(const View& v, const Laws& laws, unsigned grains) override {
    const unsigned blocks = (grains + kInspectBlock - 1) / kInspectBlock;
    if (blocks > 0) {
      laws.visit([&](const auto& model) {
        k_inspect_blocks<<<blocks, kInspectBlock, 0, stream_>>>(v, model, grains);
      });
    }
    k_inspect_total<<<1, kInspectBlock, 0, stream_>>>(v, blocks);
    CD_CUDA(cudaGetLastError());
  }
  void stiffness_time(const View& v, const Laws& laws, unsigned grains) override {
    k_stiffness_reset<<<1, 1, 0, stream_>>>(v);
    const unsigned blocks = (grains + kBlock - 1) / kBlock;
    if (blocks > 0) {
      laws.visit([&](const auto& model) {
        k_stiffness_time<<<blocks, kBlock, 0, stream_>>>(v, model, grains);
      });
    }
    CD_CUDA(cudaGetLastError());
  }
  void read_control(const View& v, Control& host) override {
    download(&host, v.ctrl, sizeof(Control));
  }

 private:
  // Grids cover the buffers' capacities (the counts live in the control block, so a graph
  // survives any change within them; a reallocation changes the view and the graph).
  void launch_forces(const View& v, const Laws& laws) {
    const int gc = grid(v.entry_capacity + v.wall_entry_capacity, kContactBlock);
    const int gp = grid(v.grain_capacity);
    laws.visit([&](const auto& model) { k_contacts<<<gc, kContactBlock, 0, stream_>>>(v, model); });
    k_gather<<<gp + static_cast<int>(v.bodies), kBlock, 0, stream_>>>(v, static_cast<unsigned>(gp));
    if (v.fail) {  // no launch without crushing
      k_crushing<<<gp, kBlock, 0, stream_>>>(v);
      k_crushing_halt<<<1, 1, 0, stream_>>>(v);
    }
  }

  void launch_step(const View& v, const Laws& laws) {
    k_kick_drift<<<grid(v.grain_capacity), kBlock, 0, stream_>>>(v);
    launch_forces(v, laws);
  }

  void capture(const View& v, const Laws& laws) {
    if (graph_) {
      CD_CUDA(cudaGraphExecDestroy(graph_));
      graph_ = nullptr;
    }
    cudaGraph_t g = nullptr;
    CD_CUDA(cudaStreamBeginCapture(stream_, cudaStreamCaptureModeThreadLocal));
    for (int s = 0; s < kGraphSteps; ++s) launch_step(v, laws);
    CD_CUDA(cudaStreamEndCapture(stream_, &g));
    const cudaError_t e = cudaGraphInstantiate(&graph_, g, 0);
    cudaGraphDestroy(g);
    CD_CUDA(e);
    graph_stale_ = false;
  }

  cudaStream_t stream_ = nullptr;
  cudaGraphExec_t graph_ = nullptr;
  bool graph_stale_ = true;
  std::vector<void*> tables_;
};

}  // namespace

std::unique_ptr<Api> make_cuda_api() {
  return std::make_unique<CudaApi>();
}

bool cuda_available() {
  int n = 0;
  if (cudaGetDeviceCount(&n) != cudaSuccess) {
    cudaGetLastError();  // clear the sticky "no device" error
    return false;
  }
  return n > 0;
}

bool cuda_built() {
  return true;
}

}  // namespace crushdem::device
