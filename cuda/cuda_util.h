// Host-side CUDA helpers for the .cu files of cuda/ (tiny-cuda-nn style): errors thrown on the host,
// only printed in destructors; device buffers that grow and never shrink.
#pragma once

#include <cuda_runtime.h>

#include <cstddef>
#include <cstdio>
#include <stdexcept>
#include <string>

namespace sl::cuda {

inline void check(cudaError_t e, const char* what) {
  if (e != cudaSuccess) throw std::runtime_error(std::string("CUDA ") + what + ": " + cudaGetErrorString(e));
}

inline void check_noexcept(cudaError_t e, const char* what) {
  if (e != cudaSuccess) std::fprintf(stderr, "sparseleap: CUDA %s: %s\n", what, cudaGetErrorString(e));
}

// Device array of T; reserve() keeps the contents only when asked.
template <class T>
class DeviceBuffer {
 public:
  DeviceBuffer() = default;
  explicit DeviceBuffer(std::size_t n) { reserve(n); }
  ~DeviceBuffer() {
    if (ptr_) check_noexcept(cudaFree(ptr_), "cudaFree");
  }
  DeviceBuffer(const DeviceBuffer&) = delete;
  DeviceBuffer& operator=(const DeviceBuffer&) = delete;

  // At least n elements; `keep`: copy the old contents over (device to device) when growing.
  void reserve(std::size_t n, bool keep = false, cudaStream_t stream = nullptr) {
    if (n <= capacity_ && ptr_) return;
    const std::size_t cap = n > 2 * capacity_ ? n : 2 * capacity_;
    T* p = nullptr;
    check(cudaMalloc(&p, (cap ? cap : 1) * sizeof(T)), "cudaMalloc");
    if (ptr_) {
      if (keep && capacity_) {
        check(cudaMemcpyAsync(p, ptr_, capacity_ * sizeof(T), cudaMemcpyDeviceToDevice, stream), "cudaMemcpy");
        check(cudaMemsetAsync(p + capacity_, 0, (cap - capacity_) * sizeof(T), stream), "cudaMemset");
        check(cudaStreamSynchronize(stream), "cudaStreamSynchronize");
      }
      check(cudaFree(ptr_), "cudaFree");
    } else if (keep) {
      check(cudaMemset(p, 0, cap * sizeof(T)), "cudaMemset");
    }
    ptr_ = p;
    capacity_ = cap;
  }
  void upload(const T* src, std::size_t n, cudaStream_t stream = nullptr) {
    reserve(n);
    if (n) check(cudaMemcpyAsync(ptr_, src, n * sizeof(T), cudaMemcpyHostToDevice, stream), "cudaMemcpyAsync");
  }
  void download(T* dst, std::size_t n, cudaStream_t stream = nullptr) const {
    if (n) check(cudaMemcpyAsync(dst, ptr_, n * sizeof(T), cudaMemcpyDeviceToHost, stream), "cudaMemcpyAsync");
  }
  T* get() const { return ptr_; }
  std::size_t capacity() const { return capacity_; }

 private:
  T* ptr_ = nullptr;
  std::size_t capacity_ = 0;
};

// Pinned host memory (page-locked), so cudaMemcpyAsync really overlaps with kernels.
class PinnedBuffer {
 public:
  PinnedBuffer() = default;
  ~PinnedBuffer() {
    if (ptr_) check_noexcept(cudaFreeHost(ptr_), "cudaFreeHost");
  }
  PinnedBuffer(const PinnedBuffer&) = delete;
  PinnedBuffer& operator=(const PinnedBuffer&) = delete;
  void reserve(std::size_t bytes) {
    if (bytes <= size_ && ptr_) return;
    if (ptr_) check(cudaFreeHost(ptr_), "cudaFreeHost");
    ptr_ = nullptr;
    size_ = bytes > 2 * size_ ? bytes : 2 * size_;
    check(cudaHostAlloc(&ptr_, size_, cudaHostAllocDefault), "cudaHostAlloc");
  }
  std::byte* get() const { return static_cast<std::byte*>(ptr_); }

 private:
  void* ptr_ = nullptr;
  std::size_t size_ = 0;
};

}  // namespace sl::cuda
