// Helpers shared by the tests of the samplers across ranks: options, the whole set on one rank
// with its noise, and vectors gathered from every rank's share.
#pragma once

#include <mpi.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "mpi_test_support.hpp"
#include "rpyfmm/mpi/direct_operator.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/random.hpp"
#include "rpyfmm/rpy/sqrt.hpp"

namespace rpyfmm_mpi_test {

inline rpyfmm::rpy::SqrtOptions sampler(rpyfmm::rpy::SqrtMethod method, rpyfmm::rpy::SqrtPreconditioner preconditioner,
                                        double tolerance) {
  rpyfmm::rpy::SqrtOptions o;
  o.method = method;
  o.preconditioner = preconditioner;
  o.tolerance = tolerance;
  return o;
}

// The whole set on one rank: the serial DirectRpy and the noise of (seed, step).
struct WholeSet {
  rpyfmm::rpy::DirectRpy op{rpyfmm::rpy::Geometry::open(), kViscosity};
  std::vector<double> z;
  WholeSet(const Particles& p, std::uint64_t seed, std::uint64_t step) : z(3 * p.size()) {
    op.set_positions(p.x, p.a);
    rpyfmm::rpy::fill_normal(z, seed, step);
  }
};

inline double relative_difference(const std::vector<double>& a, const std::vector<double>& b) {
  double d = 0.0, s = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) d += (a[i] - b[i]) * (a[i] - b[i]), s += b[i] * b[i];
  return std::sqrt(d / s);
}

// The whole vector from every rank's share (in rank order), on every rank.
inline std::vector<double> all_gather(const std::vector<double>& local) {
  const int ranks = world_size();
  int mine = static_cast<int>(local.size());
  std::vector<int> counts(static_cast<std::size_t>(ranks)), displs(static_cast<std::size_t>(ranks));
  MPI_Allgather(&mine, 1, MPI_INT, counts.data(), 1, MPI_INT, MPI_COMM_WORLD);
  int total = 0;
  for (int r = 0; r < ranks; ++r)
    displs[static_cast<std::size_t>(r)] = total, total += counts[static_cast<std::size_t>(r)];
  std::vector<double> all(static_cast<std::size_t>(total));
  MPI_Allgatherv(local.data(), mine, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE, MPI_COMM_WORLD);
  return all;
}

/// This rank's share `part` of the positions and radii of `p` on a distributed operator.
template <class Operator>
void place(Operator& op, const Particles& p, const Partition& part) {
  op.set_positions(share(p.x, 3, part.offset, part.n), share(p.a, 1, part.offset, part.n));
}

/// The bad-input tests' operator: 40 particles of radius 1, split evenly, on a DistributedDirectRpy.
struct BadInputSet {
  Particles p = uniform_particles(40, 10.0, 1.0, 1.0, 62);
  Partition part = partition_of(p.size(), Split::even);
  rpyfmm::mpi::DistributedDirectRpy op{MPI_COMM_WORLD, kViscosity};
  BadInputSet() { place(op, p, part); }
};

}  // namespace rpyfmm_mpi_test
