// rpyfmm — the wave-space part M_w of DistributedPseRpy ([PSE] eq. 19; docs/mpi.md "Distributed
// PSE"): the grid split into slabs of x planes by FFTW-MPI, spreading and interpolation on the
// slab owners.
// [PSE]: Fiore, Balboa Usabiaga, Donev & Swan, J. Chem. Phys. 146, 124116 (2017).
#pragma once

#include <array>
#include <cstddef>
#include <memory>
#include <span>
#include <vector>

#include "index_exchange.hpp"
#include "pse/wave_space.hpp"
#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/rpy/pse/pse_parameters.hpp"

namespace rpyfmm::mpi::detail {

class SlabWaveSpace {
 public:
  /// Collective: this rank's slab and the FFTW-MPI plans of the grid p.grid (double precision).
  SlabWaveSpace(const Communicator& comm, const rpy::pse::PseParameters& p, const std::array<double, 3>& box,
                double viscosity);
  ~SlabWaveSpace();
  SlabWaveSpace(const SlabWaveSpace&) = delete;
  SlabWaveSpace& operator=(const SlabWaveSpace&) = delete;

  /// Collective: this rank's positions (wrapped into the box) to the owners of the slabs their
  /// windows touch, and the windows of the particles this rank's slab receives.
  void set_positions(std::span<const double> x);
  /// Collective: out = M_w F for this rank's n particles (3 n each), plus noise_scale M_w^{1/2} z2
  /// with a noise key (the transforms shared, as PseRpy::apply_with_noise shares them).
  void apply(const double* forces, double* out, std::size_t n, const rpy::pse::detail::NoiseKey* noise = nullptr,
             double noise_scale = 0.0);
  /// Collective: [U; W] = M_w [F; T] for this rank's n particles (3 n each), the grand mobility with
  /// rotation as the serial WaveSpace::apply_rotation forms it (rotation_modes.hpp): forces and
  /// torques spread onto two sets of slabs, six transforms each way, U and W interpolated. The
  /// torque slabs are allocated by the first call.
  void apply_rotation(const double* forces, const double* torques, double* velocities, double* angular, std::size_t n);
  /// Collective: out += M_w^{1/2} z2 for this rank's n particles, z2 the wave-space noise of `key`
  /// ([PSE] eq. 21; the serial double grids' field, mode by mode).
  void add_noise(const rpy::pse::detail::NoiseKey& key, double* out, std::size_t n);
  /// Collective: [U; W] += M_w^{1/2} z2 with rotation for this rank's n particles (3 n each), as
  /// the serial WaveSpace::apply_rotation forms the noise alone: the translational field z2 of
  /// `key` scaled per mode by scale_rotation_mode (rotation_modes.hpp), so that U's part equals
  /// add_noise's for the same key to round-off. Allocates the torque slabs on the first call, as apply_rotation.
  void add_noise_rotation(const rpy::pse::detail::NoiseKey& key, double* velocities, double* angular, std::size_t n);

  /// This rank's memory for the slab of p.grid (bytes; not collective): the three components as
  /// FFTW-MPI's local size gives them (fftw_mpi_local_size_3d, with the planes and padding it asks
  /// for) and c(k) of the slab's modes, what the constructor allocates. Not counted: the torque
  /// slabs the first product with rotation allocates (as PseRpy's estimate leaves out its rotational
  /// grids) and the windows of the particles the slab receives (counted per particle by the caller).
  [[nodiscard]] static std::size_t memory_bytes(const Communicator& comm, const rpy::pse::PseParameters& p);

  /// Particles (with multiplicity) this rank sent to other slabs and received from other ranks.
  [[nodiscard]] std::size_t sent() const;
  [[nodiscard]] std::size_t received() const;
  /// The slabs' particle exchanges since set_positions (the positions, then every product's loads
  /// and velocities); not FFTW-MPI's transposes inside the transforms.
  [[nodiscard]] IndexExchange::Traffic traffic() const;

 private:
  struct Slab;
  std::unique_ptr<Slab> slab_;
};

}  // namespace rpyfmm::mpi::detail
