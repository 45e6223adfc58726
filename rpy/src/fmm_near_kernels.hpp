// Near-field kernels of FmmRpy: sums of exact RPY pair blocks over gathered sources
// (rpy_kernel.hpp, docs/theory/rpy.md; Guan eq. 3.1), for one target at a time.
#pragma once

#include <cstddef>

namespace rpyfmm::rpy::detail {

/// u = eta * sum_q M_iq f_q over the m sources (x, y, z, radius, index, force components in
/// structure-of-arrays form); the self pair (sid[q] == i) is skipped. Equal radii when sa is
/// null (radius ai).
void near_pair_sum(std::size_t m, const double* sx, const double* sy, const double* sz, const double* sa,
                   const std::size_t* sid, const double* fx, const double* fy, const double* fz, double xi, double yi,
                   double zi, double ai, std::size_t i, double u[3]);

/// Pair scalars of the target (xi, yi, zi, ai) against the m gathered sources, for several
/// right-hand sides: fs[q], gr[q] with M_iq = (fs I + gr d d^T) (times eta), d = x_i - x_q in
/// dx/dy/dz; the self pair gets fs = gr = 0. Equal radii when sa is null (radius ai).
void near_pair_scalars(std::size_t m, const double* sx, const double* sy, const double* sz, const double* sa,
                       const std::size_t* sid, double xi, double yi, double zi, double ai, std::size_t i, double* dx,
                       double* dy, double* dz, double* fs, double* gr);

/// u = sum_q (fs_q f_q + gr_q d_q (d_q . f_q)) for one right-hand side (forces in SoA).
void near_accumulate(std::size_t m, const double* dx, const double* dy, const double* dz, const double* fs,
                     const double* gr, const double* fx, const double* fy, const double* fz, double u[3]);

/// Both directions of the block between a target i and m sources of another leaf (never i
/// itself): u = sum_q M_iq f_q (times eta) is returned, and M_qi f_i (= M_iq f_i, the block is
/// symmetric) is added to (ux, uy, uz)[q]. Equal radii when sa is null (radius ai).
void near_pair_sum_symmetric(std::size_t m, const double* sx, const double* sy, const double* sz, const double* sa,
                             const double* fx, const double* fy, const double* fz, double xi, double yi, double zi,
                             double ai, const double fi[3], double* ux, double* uy, double* uz, double u[3]);

/// The same from stored pair scalars (near_pair_scalars), for one right-hand side.
void near_accumulate_symmetric(std::size_t m, const double* dx, const double* dy, const double* dz, const double* fs,
                               const double* gr, const double* fx, const double* fy, const double* fz,
                               const double fi[3], double* ux, double* uy, double* uz, double u[3]);

}  // namespace rpyfmm::rpy::detail
