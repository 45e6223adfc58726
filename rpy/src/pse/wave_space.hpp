// rpyfmm — PSE wave-space part on the CPU: Spectral Ewald with a Gaussian
// window (Lindbo & Tornberg 2010/2011), FFTW r2c/c2r with threads, race-free
// OpenMP spreading by tile colouring (docs/theory/pse.md), grids in double or
// single precision. Private.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "kernels_common.hpp"
#include "rotation_modes.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/rpy/pse/pse_parameters.hpp"

namespace rpyfmm::rpy::pse::detail {

/// Key of the wave-space noise z2: Philox (seed, step), stream kStreamWave (kernels_common.hpp).
struct NoiseKey {
  std::uint64_t seed = 0;
  std::uint64_t step = 0;
};

/// c(k) = sinc^2(ka) (1 + k^2/4xi^2) exp(-(1-eta) k^2/4xi^2) / (k^2 mu Ng) on the half
/// spectrum, zero at k = 0 and on Nyquist planes (docs/theory/pse.md). Shared with CUDA.
/// With x_end >= 0 only the planes x_begin <= ix < x_end (a slab of the MPI layer's distributed
/// grid), mode (ix, iy, iz) at ((ix - x_begin) n_y + iy) nzh + iz; `geometry` describes the whole
/// spectrum either way.
std::vector<double> wave_scaling_table(const PseParameters& p, const std::array<double, 3>& box, double viscosity,
                                       ModeGeometry& geometry, int x_begin = 0, int x_end = -1);

/// The constants of the rotational factors g(k) of one plan (rotation_modes.hpp): radius, 1 / (4 xi^2),
/// 1 - window_eta, 1 / (viscosity Ng) with Ng the grid's points, the open-boundary truncation. Shared
/// with the MPI layer's slabs.
RotationModeConstants rotation_mode_constants(const PseParameters& p, double viscosity);

/// The wave-space part M_w of one PSE plan: grids, FFT plans, the per-particle window cache.
/// make_wave_space picks the grid precision (PseParameters::wave_single).
class WaveSpace {
 public:
  virtual ~WaveSpace() = default;

  /// Window starts and weights, tile sort (positions already wrapped into the box).
  virtual void set_positions(std::span<const double> x) = 0;

  /// out (+)= M_w forces + noise_scale M_w^{1/2} z2(key). `forces` may be null
  /// (noise only, the forward FFT is skipped); `noise` may be null (deterministic).
  virtual void apply(const double* forces, double* out, bool accumulate, const NoiseKey* noise, double noise_scale,
                     StageTimes* times) = 0;

  /// [U; W] (+)= M_w [F; T] + noise_scale M_w^{1/2} z2(key) for the grand mobility with rotation
  /// (rotation_modes.hpp), 3N each: spreads forces and torques, transforms six components each way.
  /// `forces` and `torques` both null: noise only. The noise is the translational field z2, so the
  /// U part of the noise equals apply()'s to round-off. The second set of grids is allocated on the
  /// first call.
  virtual void apply_rotation(const double* forces, const double* torques, double* velocities, double* angular,
                              bool accumulate, const NoiseKey* noise, double noise_scale, StageTimes* times) = 0;
};

/// fft_measure: FFTW_MEASURE plans instead of FFTW_ESTIMATE (PseOptions::fft_measure).
/// Grids and spectra are float when p.wave_single, double otherwise.
std::unique_ptr<WaveSpace> make_wave_space(const PseParameters& p, const std::array<double, 3>& box, double viscosity,
                                           int fft_threads, bool fft_measure);

}  // namespace rpyfmm::rpy::pse::detail
