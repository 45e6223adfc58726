// rpyfmm CLI — `mpirun -np P rpyfmm rigid --method direct|fmm|pse ...` across MPI ranks
// (docs/mpi.md, "The command-line tool under mpirun"). Each rank holds whole bodies: contiguous
// runs of bodies balanced by their bead count (a rank may get none), read with --io (body_io.hpp:
// every rank its bodies' rows of the .npy files with MPI-IO, or rank 0 reads and scatters; rank 0
// reads --body-sizes). rpyfmm::mpi::DistributedRigidBodies solves on the ranks' bodies with
// DistributedDirectRpy, DistributedFmmRpy or DistributedPseRpy (in the --box) as the bead operator;
// the velocities (and the bead forces) are written to the serial command's files (a temporary file
// renamed into place) by every rank (--io collective) or by rank 0 after a gather (--io root).
#pragma once

#include <string>

#include "bead_bodies.hpp"
#include "rpyfmm/rpy/geometry.hpp"

namespace rpyfmm::cli {

struct RanksRigidArgs {
  BeadBodyArgs bodies;
  std::string forces, out, bead_forces;
  double solver_tolerance = 1e-6;  // GMRES relative residual, validated
  int max_iterations = 500;
  bool precondition = true;
  std::string method = "direct";  // direct | fmm | pse (the caller refuses others)
  double tolerance = 1e-6;        // fmm's or pse's
  double viscosity = 1.0;
  rpy::Geometry box = rpy::Geometry::open();  // pse's periodic box (--box)
  bool json = false;
  std::string io = "collective";  // --io (array_shares.hpp)
};

/// Collective over MPI_COMM_WORLD; fails on every rank alike (rpyfmm::mpi::Communicator). A build
/// without MPI throws rpyfmm::Error (not_supported).
void run_rigid_across_ranks(const RanksRigidArgs& args);

}  // namespace rpyfmm::cli
