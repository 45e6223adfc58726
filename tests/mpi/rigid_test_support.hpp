// Rigid-body test helpers shared by the MPI layer's tests of DistributedRigidBodies
// (test_distributed_rigid.cpp, test_distributed_rigid_periodic.cpp): a whole set of bodies and
// each rank's share of whole bodies under one of the splits of mpi_test_support.hpp.
#pragma once

#include <cstddef>
#include <vector>

#include "mpi_test_support.hpp"

namespace rpyfmm_mpi_test {

/// The whole set of bodies: beads body after body, one radius per bead, body offsets, and the
/// forces and torques (6 per body).
struct Bodies {
  std::vector<double> x, radii, forces_torques;
  std::vector<std::size_t> offsets{0};
  [[nodiscard]] std::size_t bodies() const { return offsets.size() - 1; }
};

/// This rank's whole bodies [first_body, first_body + bodies) and their beads.
struct LocalBodies {
  std::vector<double> x, radii, forces_torques;
  std::vector<std::size_t> offsets{0};
  std::size_t first_body = 0, bodies = 0, first_bead = 0, beads = 0;
};

/// This rank's share of `b` split by `split` over the ranks.
inline LocalBodies local_bodies(const Bodies& b, Split split) {
  const Partition p = partition_of(b.bodies(), split);
  LocalBodies l;
  l.first_body = p.offset;
  l.bodies = p.n;
  l.first_bead = b.offsets[p.offset];
  l.beads = b.offsets[p.offset + p.n] - l.first_bead;
  l.x = share(b.x, 3, l.first_bead, l.beads);
  l.radii = share(b.radii, 1, l.first_bead, l.beads);
  l.forces_torques = share(b.forces_torques, 6, p.offset, p.n);
  for (std::size_t k = 1; k <= p.n; ++k) l.offsets.push_back(b.offsets[p.offset + k] - l.first_bead);
  return l;
}

}  // namespace rpyfmm_mpi_test
