// rpyfmm — a BD run of a configuration across the ranks of an MPI communicator (docs/mpi.md,
// "Brownian dynamics across ranks"): DistributedBd behind the Integrator's engine interface
// (rpyfmm/bd/stepper.hpp), and the run options that make bd::run_bd and bd::restart_bd take their
// steps with it, rank 0 writing the trajectory, log and checkpoints.
//
//   bd::RunSummary s = bd::run_bd(config, mpi::across_ranks(MPI_COMM_WORLD));  // collective
//
// The run's files are those of the serial run with the same engine's state: with free draining
// the trajectory and the checkpoints are the serial run's byte for byte, on any number of ranks;
// with hydrodynamic interactions they follow it to round-off (direct, pse with double-precision
// wave grids) or to the FMM's tolerance.
#pragma once

#include <mpi.h>

#include <cstdint>
#include <memory>
#include <span>

#include "rpyfmm/bd/config.hpp"
#include "rpyfmm/bd/force_field.hpp"
#include "rpyfmm/bd/run.hpp"
#include "rpyfmm/bd/stepper.hpp"
#include "rpyfmm/mpi/brownian_dynamics.hpp"

namespace rpyfmm::mpi {

/// Not collective: the DistributedBd options of `config`'s run across ranks: its integrator,
/// neighbour options and viscosity, the mobility method with automatic counting as fmm in free
/// space and as pse in a periodic box (rpy::make_mobility's choice for the serial run), the FMM's
/// tolerance, and PSE's options as rpy::make_mobility gives them to PseRpy. Throws rpyfmm::Error
/// (not_supported) for pse with wave_precision single or the device cuda (PSE across ranks runs
/// double-precision grids on the CPU).
[[nodiscard]] DistributedBdOptions distributed_bd_options(const bd::RunConfig& config);

/// Not collective: rank `rank` of `ranks`' block of the whole system's particles, the global indices
/// [rank N / ranks, (rank + 1) N / ranks): their positions (3 each), types, indices, orientations
/// (4 each; only with `rotation` and given, else empty: the identity) and half-step velocities (3
/// each; only when given, else empty: the Maxwell draw with inertial types).
[[nodiscard]] BdShare block_share(int rank, int ranks, std::span<const double> positions,
                                  std::span<const std::uint32_t> types, bool rotation,
                                  std::span<const double> orientations = {}, std::span<const double> velocities = {});

/// Collective: DistributedBd for the run of `config` (its geometry, integrator with or without
/// rotation or Langevin types, neighbour options, viscosity and mobility method: none, direct or
/// fmm at its tolerance in free space, pse at its tolerance in a periodic box with double-precision
/// wave grids; automatic counts as fmm in free space and as pse in a periodic box), from the whole
/// system's positions and types at first_step, the same on every rank (with rotation also the
/// orientations, 4 per particle; empty: the identity; with Langevin types the half-step
/// velocities, 3 per particle; empty: the Maxwell draw): rank r takes the particles of its block of
/// global indices. Reading positions(), forces(), orientations(), rotations(), velocities() or,
/// with split displacements, deterministic_displacements() and brownian_displacements() or, with
/// the SAC scheme, complex_ids() gathers the whole system on rank 0 (collective, once per step; the
/// run reads the split parts every step for the log's rms columns); kinetic_temperature() and
/// complex_counts() are collective. Throws on every rank what
/// DistributedBd refuses, and for pse with wave_precision single or the device cuda.
[[nodiscard]] std::unique_ptr<bd::Stepper> make_distributed_stepper(
    MPI_Comm comm, const bd::RunConfig& config, const bd::ForceField& forces, std::span<const double> positions,
    std::span<const std::uint32_t> types, std::span<const double> orientations, std::span<const double> velocities,
    std::uint64_t first_step);

/// `options` for a run across the ranks of `comm` (every rank calls run_bd or restart_bd with
/// them): the engine above, the files written by rank 0 alone (no progress line elsewhere), and a
/// failure of rank 0's file operations made every rank's (Communicator::agree). The communicator
/// must outlive the run.
[[nodiscard]] bd::RunOptions across_ranks(MPI_Comm comm, bd::RunOptions options = {});

}  // namespace rpyfmm::mpi
