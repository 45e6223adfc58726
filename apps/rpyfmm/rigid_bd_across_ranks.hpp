// rpyfmm CLI — `mpirun -np P rpyfmm rigid-bd --method direct|fmm|pse ...` across MPI ranks
// (docs/mpi.md, "The command-line tool under mpirun"). Each rank holds whole bodies, contiguous
// runs balanced by their bead count (a rank may get none), read with --io (body_io.hpp: every rank
// its bodies' rows of the .npy files and of --restart's last frame with MPI-IO, or rank 0 reads and
// scatters; rank 0 reads --body-sizes), and builds their body-frame shapes and starting state;
// rpyfmm::mpi::DistributedRigidBodyDynamics takes the steps with DistributedDirectRpy,
// DistributedFmmRpy or DistributedPseRpy (in the --box: shapes from minimum images as the serial
// command takes them, nothing wrapped) as the bead operator; the frames and the final beads are
// written to the serial command's files (a temporary file renamed into place) by every rank (--io
// collective) or by rank 0 after a gather (--io root).
// --sqrt-preconditioner auto is none across the ranks (the principal root, the serial sampler's
// bits: rpyfmm/mpi/sqrt.hpp), so with --method direct the trajectory is the serial command's with
// --sqrt-preconditioner none up to the order of GMRES's inner-product sums; with --method pse the
// noise is the split sampler, as in the serial command. --pair runs across the ranks with the serial
// command's field (bead_pair_field; DistributedRigidBodyDynamics::set_bead_forces).
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>

#include "bead_bodies.hpp"
#include "rpyfmm/bd/force_field.hpp"
#include "rpyfmm/bd/potentials.hpp"
#include "rpyfmm/bd/rigid_dynamics.hpp"
#include "rpyfmm/rpy/geometry.hpp"

namespace rpyfmm::cli {

/// --pair between beads of different bodies: the potential (none|wca|soft|lj36_18), its energy and
/// length scales.
struct BeadPairArgs {
  std::string kind = "none";
  double epsilon = 1.0, sigma = 0.0;
};

/// The bead force field of --pair for the serial command and across the ranks alike: one bead type
/// of radius `radius` (the first bead's: a sigma of 0 is the contact distance 2 radius) and the pair
/// potential between the beads of different bodies; none for --pair none. Throws rpyfmm::Error on
/// an unknown potential or bad scales.
inline std::optional<bd::ForceField> bead_pair_field(const BeadPairArgs& pair, double radius) {
  if (pair.kind == "none") return std::nullopt;
  bd::ForceField field({bd::ParticleType{.radius = radius}});
  field.set_pair(
      0, 0,
      bd::PairPotential{.kind = bd::pair_kind_from_string(pair.kind), .epsilon = pair.epsilon, .sigma = pair.sigma});
  return field;
}

struct RanksRigidBdArgs {
  BeadBodyArgs bodies;
  std::string out, beads_out, restart;
  std::uint64_t steps = 0, every = 0;
  bd::RigidDynamicsOptions options;  // validated by the engine (collectively)
  std::array<double, 6> load{};      // --body-force then --body-torque
  std::string method = "direct";     // direct | fmm | pse (the caller refuses others)
  double tolerance = 1e-6;           // fmm's or pse's
  double viscosity = 1.0;
  rpy::Geometry box = rpy::Geometry::open();  // pse's periodic box (--box)
  BeadPairArgs pair;                          // --pair (bead_pair_field)
  bool json = false;
  std::string io = "collective";  // --io (array_shares.hpp)
};

/// Collective over MPI_COMM_WORLD; fails on every rank alike (rpyfmm::mpi::Communicator). A build
/// without MPI throws rpyfmm::Error (not_supported).
void run_rigid_bd_across_ranks(const RanksRigidBdArgs& args);

}  // namespace rpyfmm::cli
