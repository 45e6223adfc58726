// rpyfmm — periodic RPY by Positively Split Ewald on a CUDA GPU (cuFFT).
//
// Same algorithm, parameters (choose_parameters), tables and noise contract as
// the CPU operator PseRpy (pse_rpy.hpp): the per-mode scaling, the window
// weights, the real-space 3x3 blocks and the Philox streams are the same
// __host__ __device__ functions, so for the same seed and step CPU and GPU
// agree to round-off. On one device every product is the same bit for bit on every call: the
// spreading atomics add 64-bit fixed-point integers (rounded once, 2^-63 |c3| max|f| N per
// contribution), whose sum does not depend on their order. The wave grids' precision follows
// PseOptions::wave_precision as on the CPU (automatic: single precision for tolerances
// >= 1e-5, cuFFT R2C / C2R; double: D2Z / Z2D): with double grids both
// back ends agree to ~1e-12, with single grids to float round-off (~1e-7 relative, far
// below the tolerance; there the CPU also rounds its real-space pair cache to float, while the
// device keeps the real-space blocks in double). Plain C++ header (pimpl): no CUDA types leak.
//
// Built when RPYFMM_USE_CUDA is on (then RPYFMM_HAVE_CUDA_PSE is defined);
// otherwise the constructor throws ErrorCode::not_supported and
// device_available() is false. The device always evaluates the real-space part from the table
// (PseOptions::real_space_table is taken as true); fft_threads and fft_measure are FFTW
// settings and do not apply to cuFFT. Set RPYFMM_CUDA_SYNC=1 in the
// environment to check every kernel synchronously (first runs on a new device).
//
// On the device the particles are kept in slot order (the GPU radix sort's into cells, or with
// PseCudaOptions::device_cell_list off the CPU cell list's); spreading and interpolation run by
// bins of the grid through shared memory where that pays (PseCudaOptions::window_bin). A product
// uploads its forces once and downloads its velocities once (host arrays in and out, through a
// page-locked buffer), and the split sampler's
// real-space Lanczos iterates on device vectors (only its small Ritz problem is on the host),
// so only the result crosses the bus. The Lanczos basis stays allocated for the operator's
// lifetime (at most the iterations of the longest sample, 3N doubles each: ~1 GB for 50
// iterations at N = 1e6) and is not counted in the planning memory check. On one H200 at the
// [PSE] Table I setup (N = 1e6, tolerance 1e-3): M F 7.4e7 particle-timesteps per second with
// host arrays, 1.07e8 with device arrays; M^1/2 z 1.08e8 / 1.21e8 (2026-12-04, CUDA 13.0,
// 16 host cores). All work runs on
// the legacy default stream: callers that write the device arrays of apply_device /
// sample_device on other streams synchronise first.
//
// Rotation (supports_rotation) as in PseRpy (docs/theory/pse.md Sec. 5): the wave part spreads
// forces and torques onto two grids with the same window and fixed-point sums, scales each mode
// by the CPU's scale_rotation_mode (rotation_modes.hpp: the same per-mode factors and noise draw)
// and interpolates velocities and angular velocities; the real part adds the rotational rows of
// rotation_pair_terms (the CPU rows' per-pair arithmetic) over the same neighbours and the CPU's
// rotational table. apply_sqrt_rotation (automatic or split) is the split sampler on the 6N
// operator with PseRpy's noise key (the hash of [z_t; z_r]): Lanczos on S M_r S on device vectors,
// S = diag(I, a I). The second grid, its spectrum and the per-mode factors (24 bytes a mode) are
// allocated by the first call with torques of a plan; the 6N Lanczos basis doubles the
// translational one.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/rpy/mobility.hpp"
#include "rpyfmm/rpy/pse/pse_operator.hpp"
#include "rpyfmm/rpy/pse/pse_parameters.hpp"

namespace rpyfmm::rpy::pse {

/// Settings of the CUDA backend beyond PseOptions.
struct PseCudaOptions {
  /// Real-space neighbour search on the device: particles sorted into cells (edge >= r_cut) by
  /// a radix sort on the GPU, each row scanning its 27 cells, instead of the host cell list's
  /// neighbour lists uploaded at every set_positions. Same pairs (|r| < r_cut, coincident
  /// included), sums in another order. Where a box side holds fewer than 3 cells the host lists
  /// are used (see device_cell_list_active()). On by default: on an H200 at N = 1e6 (Table I)
  /// set_positions takes 0.030 s instead of 0.17 s (16 host threads building the lists), which
  /// outweighs the slower scan of the products (2026-12-04, CUDA 13.0).
  bool device_cell_list = true;
  /// Spreading and interpolation by bins through shared memory (rpy/src/pse/cuda_window.cuh):
  /// 0 = automatic (bins of the largest edge in 16, 14, ..., 4 points whose subgrids fit two
  /// blocks per multiprocessor, give >= 2 bins per multiprocessor and cut the grid atomics at
  /// least in half; else one block per particle), -1 = always one block per particle with
  /// atomics into the grid, > 0 = bins of that edge (an error at set_positions where its
  /// subgrid exceeds the device's shared memory per block). See window_bin_edge().
  int window_bin = 0;
  /// Host-array products (apply, sample, apply_with_noise, apply_sqrt) copy through one
  /// page-locked host buffer of 3N doubles (filled and emptied by the OpenMP threads) instead of
  /// pageable copies.
  bool pinned_transfers = true;
};

class PseRpyCuda final : public PseOperator {
 public:
  /// True when the library was built with CUDA and a device can be used (any
  /// CUDA error, e.g. "insufficient driver", counts as no device).
  static bool device_available();
  /// True when all `count` doubles at `values` (device memory on the current device) are finite:
  /// one pass on the device, for callers that check device inputs as the host entry points check
  /// theirs (the *_device entry points do not). Throws not_supported in a build without CUDA.
  static bool device_values_finite(const double* values, std::size_t count);

  /// Throws rpyfmm::Error for an open geometry, bad options, a build without
  /// CUDA (not_supported) or no usable device.
  PseRpyCuda(Geometry geometry, double viscosity, const PseOptions& options = {},
             const PseCudaOptions& cuda_options = {});
  ~PseRpyCuda() override;

  [[nodiscard]] std::string name() const override { return "pse-cuda"; }
  [[nodiscard]] const PseParameters& parameters() const override;
  /// True when the current positions' real-space part runs on the device cell list
  /// (PseCudaOptions::device_cell_list and at least 3 cells along every box side).
  [[nodiscard]] bool device_cell_list_active() const;
  /// The bin edge (grid points) of spreading and interpolation for the current positions; 0
  /// where they run one block per particle (PseCudaOptions::window_bin).
  [[nodiscard]] int window_bin_edge() const;

  /// w = M^{1/2} z by the split sampler keyed by (seed, step), as PseRpy::sample.
  SqrtReport sample(std::uint64_t seed, std::uint64_t step, std::span<double> w) const override;
  /// U = M F + noise_scale M^{1/2} z, as PseRpy::apply_with_noise.
  SqrtReport apply_with_noise(std::span<const double> forces, double noise_scale, std::uint64_t seed,
                              std::uint64_t step, std::span<double> velocities) const override;

  /// U = M F with F and U in device memory (3N doubles each, input order, on the current
  /// device; the caller owns them): no host transfers, for codes that keep their particles on
  /// the GPU. Returns when U is written. The pointers are not checked beyond null.
  void apply_device(const double* forces_device, double* velocities_device) const;
  /// w = M^{1/2} z by the split sampler keyed by (seed, step), as sample(), w in device memory.
  SqrtReport sample_device(std::uint64_t seed, std::uint64_t step, double* w_device) const;
  /// U = M F + noise_scale M^{1/2} z with F and U in device memory (3N doubles each, input
  /// order), as apply_with_noise: the same operations on the same slot-order vectors, so for the
  /// same forces, positions and key the same numbers. The pointers are not checked beyond null,
  /// nor the forces for finiteness. For BD on the device (docs/gpu-bd.md):
  /// noise_scale = sqrt(2 kT dt) / dt.
  SqrtReport apply_with_noise_device(const double* forces_device, double noise_scale, std::uint64_t seed,
                                     std::uint64_t step, double* velocities_device) const;
  /// Moves the particles of the last set_positions (same N, same radius, hence the same plan) to
  /// positions in device memory (3N doubles, input order, any periodic image): copied and wrapped
  /// into the box on the device as set_positions wraps them on the host, then the device cell
  /// list and the window bins rebuilt. Where the device cell list is off or does not fit (fewer
  /// than 3 cells along a box side) the wrapped positions are copied to the host for the CPU's
  /// neighbour lists, as set_positions builds them. positions() then copies them from the device
  /// on its first read. Throws before any set_positions.
  void set_positions_device(const double* positions_device);
  /// [U; W] = M [F; T] with all four in device memory (3N doubles each, input order), as
  /// apply_device. The pointers are not checked beyond null.
  void apply_device(const double* forces_device, const double* torques_device, double* velocities_device,
                    double* angular_device) const;

  [[nodiscard]] bool supports_rotation() const override { return true; }

  /// Accumulated seconds per stage, from CUDA events on the device's timeline: transfer (host
  /// <-> device copies with the gathers into and scatters from slot order), real_space, spread,
  /// fft_forward, scale, fft_backward, interpolate; lanczos (host clock: the real-space square
  /// root of the split sampler, its real-space products included); plan and positions_real
  /// (host clock: parameters, tables and cuFFT plans; cell order and neighbour lists, on the
  /// host or on the device); positions_device (events: the device cell list's sort).
  [[nodiscard]] StageTimes stage_times() const override;
  void reset_stage_times() const override;

 protected:
  void on_positions_set() override;
  void read_positions(std::vector<double>& out) const override;
  void do_apply(const double* forces, double* velocities, std::size_t nrhs) const override;
  SqrtReport do_apply_sqrt(std::span<const double> z, std::span<double> w, std::size_t nrhs,
                           const SqrtOptions& options) const override;
  void do_apply_rotation(const double* forces, const double* torques, double* velocities,
                         double* angular_velocities) const override;
  SqrtReport do_apply_sqrt_rotation(std::span<const double> z_translation, std::span<const double> z_rotation,
                                    std::span<double> w_translation, std::span<double> w_rotation,
                                    const SqrtOptions& options) const override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rpyfmm::rpy::pse
