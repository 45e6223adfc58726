// rpyfmm::bd::device — the host side of the device engine's memory: CUDA error checks that
// throw rpyfmm::Error, and an owning device array that grows only (a rebuild with fewer pairs or
// cells reuses the memory of a larger one). Included by device_engine.cu only.
#pragma once

#include <cuda_runtime.h>

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::bd::device {

inline void cuda_check(cudaError_t e, const char* what) {
  if (e == cudaSuccess) return;
  (void)cudaGetLastError();  // clear a non-sticky error
  fail(e == cudaErrorMemoryAllocation ? ErrorCode::out_of_memory : ErrorCode::numerical_failure, "bd device engine",
       std::string(what) + ": " + cudaGetErrorString(e));
}

template <class T>
class DeviceBuffer {
 public:
  DeviceBuffer() = default;
  DeviceBuffer(const DeviceBuffer&) = delete;
  DeviceBuffer& operator=(const DeviceBuffer&) = delete;
  ~DeviceBuffer() { cudaFree(data_); }

  /// Room for n items (contents lost when it grows).
  void reserve(std::size_t n) {
    if (n <= capacity_) return;
    cudaFree(data_);
    data_ = nullptr;
    capacity_ = 0;
    cuda_check(cudaMalloc(reinterpret_cast<void**>(&data_), n * sizeof(T)), "cudaMalloc");
    capacity_ = n;
  }
  void upload(const std::vector<T>& host) {
    reserve(host.size());
    if (!host.empty())
      cuda_check(cudaMemcpy(data_, host.data(), host.size() * sizeof(T), cudaMemcpyHostToDevice), "copy to the device");
  }
  /// The first n items.
  [[nodiscard]] std::vector<T> download(std::size_t n) const {
    std::vector<T> host(n);
    if (n > 0) cuda_check(cudaMemcpy(host.data(), data_, n * sizeof(T), cudaMemcpyDeviceToHost), "copy to the host");
    return host;
  }
  friend void swap(DeviceBuffer& a, DeviceBuffer& b) noexcept {
    std::swap(a.data_, b.data_);
    std::swap(a.capacity_, b.capacity_);
  }
  T* get() { return data_; }
  const T* get() const { return data_; }

 private:
  T* data_ = nullptr;
  std::size_t capacity_ = 0;
};

}  // namespace rpyfmm::bd::device
