// rpyfmm — the body mobility matrix N from its columns, one solve each, symmetrized; shared by
// rpy::RigidBodies::mobility_matrix and mpi::DistributedRigidBodies::mobility_matrix
// (body_system.hpp; docs/theory/rigid.md).
#include <string>

#include "body_system.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::rpy::rigid_detail {

void require_matrix_bodies(std::size_t m, std::size_t max_bodies, std::string_view where) {
  require(m <= max_bodies, ErrorCode::invalid_argument, where,
          "mobility_matrix of " + std::to_string(m) + " bodies needs " + std::to_string(6 * m) +
              " solves; raise max_bodies (" + std::to_string(max_bodies) + ") to allow it");
}

std::vector<double> symmetric_mobility_matrix(std::size_t n, const MobilityColumn& column) {
  std::vector<double> matrix(n * n), values(n);
  for (std::size_t c = 0; c < n; ++c) {
    column(c, values);
    for (std::size_t r = 0; r < n; ++r) matrix[r * n + c] = values[r];
  }
  for (std::size_t r = 0; r < n; ++r)
    for (std::size_t c = r + 1; c < n; ++c)
      matrix[r * n + c] = matrix[c * n + r] = 0.5 * (matrix[r * n + c] + matrix[c * n + r]);
  return matrix;
}

}  // namespace rpyfmm::rpy::rigid_detail
