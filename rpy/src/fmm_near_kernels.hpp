// Near-field kernels of FmmRpy: sums of exact RPY pair blocks over gathered sources
// (rpy_kernel.hpp, MATH.md §1; dissertation 004 eq. 3.1), for one target at a time.
#pragma once

#include <cstddef>

namespace rpyfmm::rpy::detail {

/// u = eta * sum_q M_iq f_q over the m sources (x, y, z, radius, index, force components in
/// structure-of-arrays form); the self pair (sid[q] == i) is skipped; different radii.
void near_pair_sum(std::size_t m, const double* sx, const double* sy, const double* sz, const double* sa,
                   const std::size_t* sid, const double* fx, const double* fy, const double* fz, double xi, double yi,
                   double zi, double ai, std::size_t i, double u[3]);

/// The same for equal radii a.
void near_pair_sum_equal(std::size_t m, const double* sx, const double* sy, const double* sz, const std::size_t* sid,
                         const double* fx, const double* fy, const double* fz, double xi, double yi, double zi,
                         double a, std::size_t i, double u[3]);

}  // namespace rpyfmm::rpy::detail
