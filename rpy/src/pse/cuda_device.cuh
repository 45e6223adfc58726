// rpyfmm — PSE on CUDA: the host side's device helpers (error checks, owning device and pinned
// buffers, launch sizes, stage timing by CUDA events). Included by pse_rpy_cuda.cu only.
#pragma once

#include <cuda_runtime.h>
#include <cufft.h>

#include <cstddef>
#include <cstdlib>
#include <string>
#include <vector>

#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::rpy::pse::cuda_detail {

inline constexpr const char* kWhere = "PseRpyCuda";

inline void check(cudaError_t e, const char* what) {
  if (e == cudaSuccess) return;
  (void)cudaGetLastError();  // clear a non-sticky error: later launches are judged on their own
  const ErrorCode code = e == cudaErrorMemoryAllocation ? ErrorCode::out_of_memory : ErrorCode::numerical_failure;
  fail(code, kWhere, std::string(what) + ": " + cudaGetErrorString(e));
}

inline void check_fft(cufftResult r, const char* what) {
  if (r == CUFFT_SUCCESS) return;
  const ErrorCode code = r == CUFFT_ALLOC_FAILED ? ErrorCode::out_of_memory : ErrorCode::numerical_failure;
  fail(code, kWhere, std::string(what) + ": cuFFT error " + std::to_string(static_cast<int>(r)));
}

/// After a kernel launch: launch errors always; with RPYFMM_CUDA_SYNC set in the environment,
/// also the kernel's own faults (a synchronising check, for the first runs on a new device).
inline void check_kernel(const char* what) {
  check(cudaGetLastError(), what);
  static const bool sync = std::getenv("RPYFMM_CUDA_SYNC") != nullptr;
  if (sync) check(cudaDeviceSynchronize(), what);
}

/// Owning device array.
template <class T>
class DeviceArray {
 public:
  DeviceArray() = default;
  DeviceArray(const DeviceArray&) = delete;
  DeviceArray& operator=(const DeviceArray&) = delete;
  ~DeviceArray() { cudaFree(p_); }
  void resize(std::size_t n) {
    if (n == n_ && (p_ != nullptr || n == 0)) return;
    cudaFree(p_);
    p_ = nullptr;
    n_ = 0;
    if (n > 0) {
      check(cudaMalloc(reinterpret_cast<void**>(&p_), n * sizeof(T)), "cudaMalloc");
      n_ = n;  // only once the allocation succeeded
    }
  }
  void upload(const T* host, std::size_t n) {
    resize(n);
    if (n > 0) check(cudaMemcpy(p_, host, n * sizeof(T), cudaMemcpyHostToDevice), "cudaMemcpy to device");
  }
  void download(T* host, std::size_t n) const {
    if (n > 0) check(cudaMemcpy(host, p_, n * sizeof(T), cudaMemcpyDeviceToHost), "cudaMemcpy to host");
  }
  T* get() { return p_; }
  const T* get() const { return p_; }
  [[nodiscard]] std::size_t size() const { return n_; }

 private:
  T* p_ = nullptr;
  std::size_t n_ = 0;
};

/// Owning page-locked host buffer (grows only).
class PinnedBuffer {
 public:
  PinnedBuffer() = default;
  PinnedBuffer(const PinnedBuffer&) = delete;
  PinnedBuffer& operator=(const PinnedBuffer&) = delete;
  ~PinnedBuffer() { cudaFreeHost(p_); }
  double* reserve(std::size_t n) {
    if (n > n_) {
      cudaFreeHost(p_);
      p_ = nullptr;
      n_ = 0;
      check(cudaMallocHost(reinterpret_cast<void**>(&p_), n * sizeof(double)), "cudaMallocHost");
      n_ = n;
    }
    return p_;
  }

 private:
  double* p_ = nullptr;
  std::size_t n_ = 0;
};

/// Bits of the radix sort's keys for keys below `count`.
inline int key_bits(std::size_t count) {
  int bits = 1;
  while (bits < 32 && (std::size_t{1} << bits) < count) ++bits;
  return bits;
}

constexpr unsigned kThreads = 256;       // element-wise kernels
constexpr unsigned kReduceBlocks = 240;  // inner products: fixed, so their sums do not depend on the device

inline unsigned blocks_for(std::size_t n, unsigned threads) {
  return static_cast<unsigned>((n + threads - 1) / threads);
}

/// Wall-clock seconds of the device's stages, from CUDA events (the stream's own timeline);
/// read (and accumulated) once the product's result has been downloaded.
class StageEvents {
 public:
  StageEvents() = default;
  StageEvents(const StageEvents&) = delete;
  StageEvents& operator=(const StageEvents&) = delete;
  ~StageEvents() {
    for (auto& e : pool_) cudaEventDestroy(e);
  }
  /// Marks the start of `stage` on the default stream.
  void begin(const char* stage) { open_.push_back({stage, record()}); }
  /// Marks the end of the stage begun last.
  void end() {
    if (open_.empty()) return;
    const Open o = open_.back();
    open_.pop_back();
    done_.push_back({o.stage, o.event, record()});
  }
  /// Adds the finished stages' times to `times` (waits for their events) and recycles the
  /// events; called where no stage is open (a stage left open by an exception is dropped).
  void collect(StageTimes& times) {
    std::vector<Done> done;
    done.swap(done_);
    open_.clear();
    used_ = 0;
    for (const Done& d : done) {
      check(cudaEventSynchronize(pool_[d.stop]), "cudaEventSynchronize");
      float ms = 0.0F;
      check(cudaEventElapsedTime(&ms, pool_[d.start], pool_[d.stop]), "cudaEventElapsedTime");
      times[d.stage] += 1e-3 * static_cast<double>(ms);
    }
  }

 private:
  struct Open {
    const char* stage;
    std::size_t event;
  };
  struct Done {
    const char* stage;
    std::size_t start, stop;
  };
  std::size_t record() {
    if (used_ == pool_.size()) {
      cudaEvent_t e{};
      check(cudaEventCreate(&e), "cudaEventCreate");
      pool_.push_back(e);
    }
    check(cudaEventRecord(pool_[used_], 0), "cudaEventRecord");
    return used_++;
  }
  std::vector<cudaEvent_t> pool_;
  std::size_t used_ = 0;
  std::vector<Open> open_;
  std::vector<Done> done_;
};

}  // namespace rpyfmm::rpy::pse::cuda_detail
