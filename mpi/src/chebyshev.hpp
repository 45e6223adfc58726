// rpyfmm — equivalent charges of a cell at tensor Chebyshev nodes: the anterpolation of the
// black-box FMM (Fong & Darve, J. Comput. Phys. 228 (2009) 8712, Sec. 2; docs/mpi.md, "Distributed
// Laplace FMM").
//
// With the p Chebyshev points of the first kind t_m = cos((2m + 1) pi / (2p)) on [-1, 1] and
//   S_p(t_m, t) = 1/p + 2/p sum_{k=1}^{p-1} T_k(t_m) T_k(t),
// the interpolant of a smooth f on the cube (center c, half-side h) is
//   f(y) ~ sum_{a,b,c} f(x_abc) S_p(t_a, u_x) S_p(t_b, u_y) S_p(t_c, u_z),   u = (y - c) / h,
// with x_abc = c + h (t_a, t_b, t_c). Applied to f(y) = 1 / |x - y| for a target x far from the cube,
//   sum_j q_j / |x - y_j| ~ sum_{abc} Q_abc / |x - x_abc|,   Q_abc = sum_j q_j S_p(t_a, u_x,j) ...,
// so the cell's particles act on far targets as the charges Q at the p^3 nodes.
#pragma once

#include <cstddef>
#include <span>

#include "cell_tree.hpp"

namespace rpyfmm::mpi::detail {

/// The p^3 node positions x_abc of a cube, 3 each, node index (a p + b) p + c with a along x.
void chebyshev_nodes(const Cube& cube, int p, std::span<double> nodes);

/// The equivalent charges of particles (3 per particle in `positions`, all inside the cube) with
/// charges q[d * ldq + j] (j < positions.size() / 3, d < nd): out[d * p^3 + node] is overwritten.
void anterpolate(const Cube& cube, int p, std::span<const double> positions, const double* q, std::size_t ldq,
                 std::size_t nd, std::span<double> out);

}  // namespace rpyfmm::mpi::detail
