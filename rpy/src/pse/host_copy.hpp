// rpyfmm — PSE on CUDA: host-side copies by the OpenMP threads (staging the host arrays of a
// product through a page-locked buffer; a plain C++ unit, since nvcc does not compile OpenMP
// host code here).
#pragma once

#include <cstddef>

namespace rpyfmm::rpy::pse::detail {

/// dst[0, n) = src[0, n) in chunks over the OpenMP threads (the arrays must not overlap).
void parallel_copy(double* dst, const double* src, std::size_t n);

}  // namespace rpyfmm::rpy::pse::detail
