// rpyfmm — PseRpyCuda::device_values_finite: a finiteness check of device arrays, for callers
// (the Python bindings) that validate device inputs as the host entry points validate theirs.
#include <cuda_runtime.h>

#include <cstddef>
#include <string>

#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/pse/pse_rpy_cuda.hpp"

namespace rpyfmm::rpy::pse {
namespace {

// Sets *flag to 1 where a value is NaN or infinite (every writer writes the same 1).
__global__ void flag_non_finite(const double* values, std::size_t count, int* flag) {
  const std::size_t stride = static_cast<std::size_t>(gridDim.x) * blockDim.x;
  for (std::size_t i = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x; i < count; i += stride)
    if (!isfinite(values[i])) *flag = 1;
}

void check(cudaError_t status, const char* call) {
  if (status != cudaSuccess)
    fail(ErrorCode::numerical_failure, "PseRpyCuda::device_values_finite",
         std::string(call) + " failed: " + cudaGetErrorString(status));
}

}  // namespace

bool PseRpyCuda::device_values_finite(const double* values, std::size_t count) {
  if (count == 0) return true;
  require(values != nullptr, ErrorCode::invalid_input, "PseRpyCuda::device_values_finite", "null device pointer");
  int* flag = nullptr;
  check(cudaMalloc(&flag, sizeof(int)), "cudaMalloc");
  int host_flag = 0;
  cudaError_t status = cudaMemset(flag, 0, sizeof(int));
  if (status == cudaSuccess) {
    constexpr unsigned kThreads = 256;
    const std::size_t wanted = (count + kThreads - 1) / kThreads;
    const unsigned blocks = static_cast<unsigned>(wanted < 1024 ? wanted : 1024);
    flag_non_finite<<<blocks, kThreads>>>(values, count, flag);
    status = cudaGetLastError();
  }
  if (status == cudaSuccess) status = cudaMemcpy(&host_flag, flag, sizeof(int), cudaMemcpyDeviceToHost);
  cudaFree(flag);
  check(status, "the finiteness check");
  return host_flag == 0;
}

}  // namespace rpyfmm::rpy::pse
