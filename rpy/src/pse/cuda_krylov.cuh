// rpyfmm — PSE on CUDA: the Lanczos basis of the split sampler's real-space square root on the
// device (sqrt_detail::KrylovSpace) and its vector kernels. Inner products are summed in a fixed
// order (kReduceBlocks partial sums, added on the host in block order): deterministic.
// Included by pse_rpy_cuda.cu only.
#pragma once

#include <cuda_runtime.h>

#include <algorithm>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "../sqrt/krylov_space.hpp"
#include "cuda_device.cuh"
#include "cuda_window.cuh"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::rpy::pse::cuda_detail {

using cuda_window::block_sum;
using cuda_window::kWarp;

/// partial[b] = sum over block b's grid-stride share of x[q] y[q] (kReduceBlocks blocks).
__global__ void dot_partial_kernel(std::size_t n, const double* __restrict__ x, const double* __restrict__ y,
                                   double* __restrict__ partial) {
  __shared__ double warps[kThreads / kWarp];
  double s = 0.0;
  for (std::size_t q = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x; q < n;
       q += static_cast<std::size_t>(gridDim.x) * blockDim.x)
    s += x[q] * y[q];
  s = block_sum(s, warps);
  if (threadIdx.x == 0) partial[blockIdx.x] = s;
}

__global__ void axpy_kernel(std::size_t n, double a, const double* __restrict__ x, double* __restrict__ y) {
  const std::size_t q = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (q < n) y[q] += a * x[q];
}

/// y += a x on n device doubles.
inline void device_axpy(std::size_t n, double a, const double* x, double* y) {
  axpy_kernel<<<blocks_for(n, kThreads), kThreads>>>(n, a, x, y);
  check_kernel("axpy kernel");
}

__global__ void scale_into_kernel(std::size_t n, double a, const double* x, double* out) {
  const std::size_t q = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (q < n) out[q] = a * x[q];
}

/// first[0] = min index q with a non-finite y[q] (stays at its initial n when there is none).
__global__ void first_nonfinite_kernel(std::size_t n, const double* __restrict__ y, unsigned long long* first) {
  const std::size_t q = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (q < n && !isfinite(y[q])) atomicMin(first, static_cast<unsigned long long>(q));
}

/// The Lanczos basis in device memory: one allocation per basis vector, kept across samples.
class DeviceKrylovSpace final : public sqrt_detail::KrylovSpace {
 public:
  void set_size(std::size_t n) {
    if (n == n_) return;
    n_ = n;
    store_.clear();
    count_ = 0;
    work_.resize(0);
  }
  [[nodiscard]] std::size_t n() const override { return n_; }
  void clear() override { count_ = 0; }
  double* push() override {
    if (count_ == store_.size()) {
      auto v = std::make_unique<DeviceArray<double>>();
      v->resize(n_);  // allocated before it joins the basis: a failed cudaMalloc leaves no null entry
      store_.push_back(std::move(v));
    }
    return store_[count_++]->get();
  }
  [[nodiscard]] double* vector(std::size_t q) override { return store_[q]->get(); }
  [[nodiscard]] std::size_t basis_size() const override { return count_; }
  [[nodiscard]] double* work() override {
    work_.resize(n_);
    return work_.get();
  }
  double dot(const double* x, const double* y) override {
    double h = 0.0;
    dots_of({x}, y, &h);
    return h;
  }
  void dots(std::size_t k, const double* y, double* h) override {
    std::vector<const double*> v(k);
    for (std::size_t q = 0; q < k; ++q) v[q] = store_[q]->get();
    dots_of(v, y, h);
  }
  void subtract_combination(std::size_t k, const double* h, double* y) override {
    for (std::size_t q = 0; q < k; ++q) axpy(-h[q], store_[q]->get(), y);
  }
  void axpy(double a, const double* x, double* y) override { device_axpy(n_, a, x, y); }
  void scale_into(double a, const double* x, double* out) override {
    scale_into_kernel<<<blocks_for(n_, kThreads), kThreads>>>(n_, a, x, out);
    check_kernel("scale kernel (Lanczos)");
  }
  void combine(std::size_t k, const double* c, double* out) override {
    check(cudaMemset(out, 0, n_ * sizeof(double)), "cudaMemset");
    for (std::size_t q = 0; q < k; ++q) axpy(c[q], store_[q]->get(), out);
  }
  void require_finite(const double* y, const char* where, long long product) override {
    flag_.resize(1);
    const auto none = static_cast<unsigned long long>(n_);
    check(cudaMemcpy(flag_.get(), &none, sizeof(none), cudaMemcpyHostToDevice), "cudaMemcpy to device");
    first_nonfinite_kernel<<<blocks_for(n_, kThreads), kThreads>>>(n_, y, flag_.get());
    check_kernel("finiteness kernel");
    unsigned long long first = none;
    flag_.download(&first, 1);
    if (first < none) {
      fail(ErrorCode::numerical_failure, where,
           "the operator returned a non-finite value (entry " + std::to_string(first) +
               " of right-hand side 0, slot order) at product " + std::to_string(product));
    }
  }

 private:
  /// h[q] = v[q] . y: kReduceBlocks partial sums per vector on the device, added on the host in
  /// block order (deterministic).
  void dots_of(const std::vector<const double*>& v, const double* y, double* h) {
    const std::size_t need = std::max<std::size_t>(1, v.size()) * kReduceBlocks;
    if (partial_.size() < need) partial_.resize(2 * need);  // grows only: no allocation per call
    for (std::size_t q = 0; q < v.size(); ++q) {
      dot_partial_kernel<<<kReduceBlocks, kThreads>>>(n_, v[q], y, partial_.get() + q * kReduceBlocks);
      check_kernel("dot kernel");
    }
    host_partial_.resize(v.size() * kReduceBlocks);
    partial_.download(host_partial_.data(), host_partial_.size());
    for (std::size_t q = 0; q < v.size(); ++q) {
      double s = 0.0;
      for (unsigned b = 0; b < kReduceBlocks; ++b) s += host_partial_[q * kReduceBlocks + b];
      h[q] = s;
    }
  }

  std::size_t n_ = 0;
  std::vector<std::unique_ptr<DeviceArray<double>>> store_;
  std::size_t count_ = 0;
  DeviceArray<double> work_, partial_;
  DeviceArray<unsigned long long> flag_;
  std::vector<double> host_partial_;
};

}  // namespace rpyfmm::rpy::pse::cuda_detail
