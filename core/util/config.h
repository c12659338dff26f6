// Shared compile-time configuration for code that both the host compiler and nvcc build.
#pragma once

// SL_HOST_DEVICE marks functions that the CPU backend and the CUDA kernels both compile
// (the way pbrt-v4's PBRT_CPU_GPU and NanoVDB's __hostdev__ work). core/ never includes a CUDA header.
#if defined(__CUDACC__)
#define SL_HOST_DEVICE __host__ __device__
#define SL_DEVICE_CODE 1
#else
#define SL_HOST_DEVICE
#define SL_DEVICE_CODE 0
#endif

// SL_INLINE forces inlining of the per-sample helpers: a call per sample (returning a vec4 through
// the stack) cost as much as the sample itself in the profile of the CPU caster.
#if defined(__CUDACC__)
#define SL_INLINE __forceinline__
#elif defined(__GNUC__)
#define SL_INLINE inline __attribute__((always_inline))
#else
#define SL_INLINE inline
#endif

// SL_DEVICE_NOINLINE keeps a large, rarely taken path (the B-spline filters, lit labels) out of line in
// the kernels, and SL_DEVICE_NO_UNROLL keeps a loop over sampler calls rolled there: inlined and
// unrolled into every kernel they multiplied ptxas's time several-fold. The host compiler decides alone.
#if defined(__CUDACC__)
#define SL_DEVICE_NOINLINE __noinline__
#else
#define SL_DEVICE_NOINLINE
#endif
#if defined(__CUDA_ARCH__)
#define SL_DEVICE_NO_UNROLL _Pragma("unroll 1")
#else
#define SL_DEVICE_NO_UNROLL
#endif

#if !defined(__CUDA_ARCH__)
#include <cassert>
#include <stdexcept>
#include <string>
#endif

namespace sl {

#if !defined(__CUDA_ARCH__)
// Always-on check of an internal invariant (not of user input: that throws InputError).
[[noreturn]] inline void check_failed(const char* expr, const char* file, int line) {
  throw std::logic_error(std::string("internal check failed: ") + expr + " at " + file + ":" +
                         std::to_string(line));
}
#endif

}  // namespace sl

#if defined(__CUDA_ARCH__)
#define SL_CHECK(cond) assert(cond)
#else
#define SL_CHECK(cond) \
  do { \
    if (!(cond)) ::sl::check_failed(#cond, __FILE__, __LINE__); \
  } while (0)
#endif

#ifdef NDEBUG
#define SL_DCHECK(cond) ((void)0)
#else
#define SL_DCHECK(cond) assert(cond)
#endif
