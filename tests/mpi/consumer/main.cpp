// An outside user of the installed rpyfmm::mpi: the distributed direct operator through the
// installed headers on every rank's share of two spheres, against the serial DirectRpy.
#include <mpi.h>

#include <cstdio>
#include <vector>

#include "rpyfmm/mpi/direct_operator.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"

int main(int argc, char** argv) {
  int provided = 0;
  MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  const std::vector<double> x = {0.0, 0.0, 0.0, 3.0, 0.0, 0.0}, f = {1.0, 0.0, 0.0, 0.0, 1.0, 0.0};
  rpyfmm::rpy::DirectRpy serial;
  serial.set_positions(x, 1.0);
  std::vector<double> u_serial(6);
  serial.apply(f, u_serial);
  // Rank 0 holds both spheres, the other ranks none.
  const std::size_t n = rank == 0 ? 2 : 0;
  rpyfmm::mpi::DistributedDirectRpy op(MPI_COMM_WORLD);
  op.set_positions(std::vector<double>(x.begin(), x.begin() + 3 * n), 1.0);
  std::vector<double> u(3 * n);
  op.apply(std::vector<double>(f.begin(), f.begin() + 3 * n), u);
  int ok = u == std::vector<double>(u_serial.begin(), u_serial.begin() + 3 * n) ? 1 : 0, all = 0;
  MPI_Allreduce(&ok, &all, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
  if (rank == 0) std::printf("rpyfmm::mpi consumer on %d ranks: %s\n", op.communicator().size(), all ? "ok" : "FAILED");
  MPI_Finalize();
  return all ? 0 : 1;
}
