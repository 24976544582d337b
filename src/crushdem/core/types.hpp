// Basic numeric types and the host/device marker used by every physics kernel.
// Kernels are header-only functions marked CD_HD so that the same code compiles for the CPU
// loop and for a CUDA kernel (HOOMD-blue's evaluator pattern).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

#if defined(__CUDACC__)
#define CD_HD __host__ __device__
#else
#define CD_HD
#endif

// For the per-contact kernels that vector loops call (pair_contact() and what it calls): always
// inlined. Left to GCC's budget, a translation unit with many instantiations of the pair loop
// stops inlining some of them, and a loop that calls a function does not vectorise.
#if defined(__CUDACC__)
#define CD_HD_INLINE __host__ __device__ __forceinline__
#elif defined(__GNUC__)
#define CD_HD_INLINE [[gnu::always_inline]] inline
#else
#define CD_HD_INLINE inline
#endif

namespace crushdem {

/// Stable particle identifier: assigned once, never reused (fragments get fresh ids).
using ParticleId = std::uint64_t;
inline constexpr ParticleId kNoParent = ~ParticleId{0};

struct Vec3 {
  double x = 0.0, y = 0.0, z = 0.0;
};

CD_HD inline Vec3 operator+(Vec3 a, Vec3 b) {
  return {a.x + b.x, a.y + b.y, a.z + b.z};
}
CD_HD inline Vec3 operator-(Vec3 a, Vec3 b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}
CD_HD inline Vec3 operator-(Vec3 a) {
  return {-a.x, -a.y, -a.z};
}
CD_HD inline Vec3 operator*(double s, Vec3 a) {
  return {s * a.x, s * a.y, s * a.z};
}
CD_HD inline Vec3 operator*(Vec3 a, double s) {
  return {s * a.x, s * a.y, s * a.z};
}
CD_HD inline Vec3& operator+=(Vec3& a, Vec3 b) {
  a.x += b.x;
  a.y += b.y;
  a.z += b.z;
  return a;
}
CD_HD inline Vec3& operator-=(Vec3& a, Vec3 b) {
  a.x -= b.x;
  a.y -= b.y;
  a.z -= b.z;
  return a;
}
CD_HD inline double dot(Vec3 a, Vec3 b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
CD_HD inline Vec3 cross(Vec3 a, Vec3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
CD_HD inline double norm(Vec3 a) {
  return std::sqrt(dot(a, a));
}

/// v's components into x[k], y[k], z[k]: a store into struct-of-arrays columns.
CD_HD_INLINE void store(double* x, double* y, double* z, std::size_t k, Vec3 v) {
  x[k] = v.x;
  y[k] = v.y;
  z[k] = v.z;
}

inline constexpr double kPi = 3.14159265358979323846;

}  // namespace crushdem
