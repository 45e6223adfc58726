// rpyfmm — DirectRpy's pair sums on sources held in pieces (private to the library and rpyfmm::mpi).
//
// DirectRpy sums the velocity of each target over source blocks of kDirectBlock in increasing
// order (direct_operator.cpp), and with rotation the rotational pair terms of U and W likewise
// (direct_rotation.cpp). A caller that receives the sources in pieces in their global order, each
// piece starting at a multiple of kDirectBlock, and adds every piece with add_direct_block_sums
// (and add_rotation_block_sums) to the same accumulators, performs the same operations in the same
// order: its sums are DirectRpy's bit for bit (rpyfmm::mpi::DistributedDirectRpy, docs/mpi.md).
#pragma once

#include <cstddef>
#include <span>
#include <vector>

#include "length_units.hpp"
#include "rotation_pair_sums.hpp"

namespace rpyfmm::rpy::detail {

/// Sources per block: the pair scalars of one block stay in L1.
inline constexpr std::size_t kDirectBlock = 256;

/// Particles in structure-of-arrays form, in the operator's length units (length_units.hpp), with
/// inv_a[j] = 1.0 / a[j].
struct DirectParticles {
  const double* x = nullptr;
  const double* y = nullptr;
  const double* z = nullptr;
  const double* a = nullptr;
  const double* inv_a = nullptr;
};

/// Forces in structure-of-arrays form, already load-scaled (load_scaling.hpp).
struct DirectForces {
  const double* x = nullptr;
  const double* y = nullptr;
  const double* z = nullptr;
};

/// The arrays DirectRpy keeps of its particles (DirectParticles' storage).
struct DirectParticleArrays {
  std::vector<double>& x;
  std::vector<double>& y;
  std::vector<double>& z;
  std::vector<double>& a;
  std::vector<double>& inv_a;
};

/// Positions (3n) and radii (n) as DirectRpy stores them: in `units`, as structure of arrays, with
/// inv_a = 1.0 / a.
void store_direct_particles(std::span<const double> positions, std::span<const double> radii, const LengthUnits& units,
                            const DirectParticleArrays& out);

/// acc[3 (nrhs i + k) + c] += the sums of target i (i < n_targets) for the right-hand side
/// forces[k] (k < nrhs = forces.size()) over sources [0, n_sources), block by block of kDirectBlock
/// (the last one may be shorter), each block's sum added in increasing order as DirectRpy does. The
/// pair scalars of a block are evaluated once for all right-hand sides, and each right-hand side's
/// sums are the operations of a product with it alone. Not yet divided by the viscosity nor scaled
/// back from the length units. With equal_radii every radius is targets.a[0] (DirectRpy's
/// equal-radii path). Parallel over targets with OpenMP; each target is summed by one thread, so
/// the result does not depend on the threads.
void add_direct_block_sums(const DirectParticles& targets, std::size_t n_targets, const DirectParticles& sources,
                           std::span<const DirectForces> forces, std::size_t n_sources, bool equal_radii, double* acc);

/// acc[6 i + c] += the rotational sums of target i (i < n_targets) of rotation_pair_sum, U for
/// c < 3 and W for c >= 3, over the sources [0, sources.m), block by block of kDirectBlock (the last
/// one may be shorter), each block's sums added in increasing order as DirectRpy does. Target i is
/// particle first_target + i of the whole set, sources.id the sources' indices in it (the self pair
/// is skipped by index); targets.inv_a is not read. In the units of rotation_pair_sums.hpp, not yet
/// divided by the viscosity. Parallel over targets with OpenMP, each target summed by one thread.
void add_rotation_block_sums(const DirectParticles& targets, std::size_t first_target, std::size_t n_targets,
                             const GrandSources& sources, double* acc);

}  // namespace rpyfmm::rpy::detail
