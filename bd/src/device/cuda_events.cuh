// rpyfmm::bd::device — the device engine's stage timer: CUDA events recorded between a step's
// stages (before the lists, after them, after the forces, after the update), read once the step's
// status has come back (the events have completed by then), for the seconds per part that the
// Table 2 of Tran et al. (2015) reports and the CPU engine's IntegratorTotals keeps ("neighbours",
// "forces", "update"). Included by device_engine.cu only.
#pragma once

#include <cuda_runtime.h>

#include "cuda_buffer.cuh"

namespace rpyfmm::bd::device {

class StageEvents {
 public:
  static constexpr int kMarks = 5;

  StageEvents() {
    for (auto& e : events_) cuda_check(cudaEventCreate(&e), "cudaEventCreate");
  }
  StageEvents(const StageEvents&) = delete;
  StageEvents& operator=(const StageEvents&) = delete;
  ~StageEvents() {
    for (auto e : events_) cudaEventDestroy(e);
  }

  /// Records mark k (0 <= k < kMarks) on the default stream.
  void mark(int k) { cuda_check(cudaEventRecord(events_[k]), "cudaEventRecord"); }
  /// Seconds from mark a to mark b (both recorded and completed).
  [[nodiscard]] double seconds(int a, int b) const {
    float ms = 0.0f;
    cuda_check(cudaEventElapsedTime(&ms, events_[a], events_[b]), "cudaEventElapsedTime");
    return 1e-3 * static_cast<double>(ms);
  }

 private:
  cudaEvent_t events_[kMarks] = {};
};

}  // namespace rpyfmm::bd::device
