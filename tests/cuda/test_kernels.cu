// The contact kernels on the GPU: the same header-only functions the CPU loop uses, evaluated in
// a CUDA kernel on random contacts and compared with the host. Built with -fmad=false and IEEE
// division and square root (nvcc's defaults), so the results must be bit-identical.
// Prints "N passed, M failed" as its last line; exit code 0 only when all pass.
#include <cuda_runtime.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <vector>

#include "crushdem/contact/contact_kernel.hpp"
#include "crushdem/core/random.hpp"

using namespace crushdem;

struct Input {
  double delta, R_star, m_eff;
  Vec3 n, v_rel, F_t;
};

template <class Law>
__global__ void evaluate(Law law, ContactParams cp, const Input* in, ContactResponse* out, int n,
                         double dt) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= n) return;
  const Input c = in[k];
  out[k] = contact_response(law, c.delta, c.R_star, sqrt(c.R_star), c.m_eff, c.n, c.v_rel, c.F_t,
                            cp.mu, cp, dt);
}

#define CHECK_CUDA(x)                                                                        \
  do {                                                                                       \
    cudaError_t err_ = (x);                                                                  \
    if (err_ != cudaSuccess) {                                                               \
      std::printf("CUDA error %s at %s:%d\n", cudaGetErrorString(err_), __FILE__, __LINE__); \
      std::printf("0 passed, 1 failed\n");                                                   \
      std::exit(1);                                                                          \
    }                                                                                        \
  } while (0)

// Copies a table block to the device (the whole block: the kernel picks a table by an offset).
const double* to_device(const TableBlock& b, std::vector<double*>& owned) {
  double* d = nullptr;
  CHECK_CUDA(cudaMalloc(&d, sizeof(double) * b.count));
  CHECK_CUDA(cudaMemcpy(d, b.host, sizeof(double) * b.count, cudaMemcpyHostToDevice));
  owned.push_back(d);
  return d;
}

template <class Law>
bool compare(const char* name, const Law& host_law, const Law& device_law, const ContactParams& cp,
             const std::vector<Input>& in) {
  const int n = static_cast<int>(in.size());
  Input* d_in = nullptr;
  ContactResponse* d_out = nullptr;
  CHECK_CUDA(cudaMalloc(&d_in, sizeof(Input) * n));
  CHECK_CUDA(cudaMalloc(&d_out, sizeof(ContactResponse) * n));
  CHECK_CUDA(cudaMemcpy(d_in, in.data(), sizeof(Input) * n, cudaMemcpyHostToDevice));
  const double dt = 1e-8;
  evaluate<<<(n + 127) / 128, 128>>>(device_law, cp, d_in, d_out, n, dt);
  CHECK_CUDA(cudaGetLastError());
  std::vector<ContactResponse> gpu(n);
  CHECK_CUDA(cudaMemcpy(gpu.data(), d_out, sizeof(ContactResponse) * n, cudaMemcpyDeviceToHost));
  cudaFree(d_in);
  cudaFree(d_out);
  int mismatches = 0, touching = 0;
  for (int k = 0; k < n; ++k) {
    const Input& c = in[k];
    const ContactResponse h = contact_response(host_law, c.delta, c.R_star, std::sqrt(c.R_star),
                                               c.m_eff, c.n, c.v_rel, c.F_t, cp.mu, cp, dt);
    touching += h.F_n > 0.0;
    if (std::memcmp(&h, &gpu[k], sizeof h) != 0) {
      if (mismatches < 3) {
        std::printf("  %s contact %d: host F_n %.17g gpu %.17g\n", name, k, h.F_n, gpu[k].F_n);
      }
      ++mismatches;
    }
  }
  std::printf("%s: %d contacts (%d touching), %d differ from the host\n", name, n, touching,
              mismatches);
  return mismatches == 0 && touching > n / 2;
}

int main() {
  int devices = 0;
  if (cudaGetDeviceCount(&devices) != cudaSuccess || devices == 0) {
    std::printf("no CUDA device\n0 passed, 1 failed\n");
    return 1;
  }
  RandomStream rng(7);
  std::vector<Input> in(200000);
  for (Input& c : in) {
    c.delta = rng.uniform(-1e-7, 6e-6);  // all regimes of the rough law, and separation
    c.R_star = rng.uniform(5e-6, 1.4e-4);
    c.m_eff = rng.uniform(1e-10, 2e-8);
    Vec3 n{rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)};
    c.n = (1.0 / norm(n)) * n;
    c.v_rel = {rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1)};
    c.F_t = {rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05)};
  }
  MaterialConfig m;
  ContactConfig cc;
  cc.restitution = 0.5;  // exercise the viscous part too
  int passed = 0, failed = 0;
  {
    cc.law = NormalLaw::Hertz;
    const ContactLaw law(m, cc);
    const HertzLaw hertz = law.pair_law<HertzNormal>();
    (compare("hertz", hertz, hertz, law.params(), in) ? passed : failed)++;
  }
  std::vector<double*> owned;
  for (auto [k1, k2] : {std::pair{0.05, 5.0}, std::pair{1.0, 100.0}}) {
    cc.law = NormalLaw::Rough;
    cc.k1 = k1;
    cc.k2 = k2;
    const ContactLaw law(m, cc);
    const RoughHertzLaw host = law.pair_law<RoughNormal>();
    RoughHertzLaw dev = host;
    dev.nodes = to_device(law.tables()[0], owned);
    (compare(k1 < 0.5 ? "rough(0.05,5)" : "rough(1,100)", host, dev, law.params(), in) ? passed
                                                                                       : failed)++;
  }
  for (double* d : owned) cudaFree(d);
  std::printf("%d passed, %d failed\n", passed, failed);
  return failed == 0 ? 0 : 1;
}
