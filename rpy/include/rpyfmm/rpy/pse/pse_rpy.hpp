// rpyfmm — periodic RPY mobility by Positively Split Ewald on the CPU
// (Fiore, Balboa Usabiaga, Donev & Swan, J. Chem. Phys. 146, 124116 (2017); the method in the
// project's words: docs/theory/pse.md).
//
//   M = M_r + M_w, both SPD ([PSE] Sec. II.A, App. B):
//   - M_r: closed forms F, G of [PSE] App. A, cut at r_cut, cell/neighbour lists, minimum image;
//   - M_w: Spectral Ewald (Gaussian spreading on P^3 points, FFTW r2c, scaling
//     (1/(eta V)) sinc^2(ka) H(k, xi)/k^2 (I - khat khat), c2r, interpolation), on float
//     grids for tolerances >= 1e-5 (PseOptions::wave_precision; ~1e-7 added error).
//
// Brownian noise, split sampler ([PSE] eq. 17-21):  M^{1/2} z = M_r^{1/2} z1 + M_w^{1/2} z2,
//   z1: Lanczos on M_r alone (sqrt_apply), z2: complex Gaussian Fourier field with
//   z2(-k) = conj z2(k), drawn from Philox keyed by (seed, step, stream 2/3, mode).
// Noise derivation (documented contract):
//   - sample(seed, step, w) / apply_with_noise(...): z1 = fill_normal(seed, step, stream 1)
//     (random.hpp), z2 from (seed, step). Reproducible, thread-count independent, and the
//     same on CPU and CUDA (to round-off, with double-precision wave grids on the CPU).
//   - apply_sqrt(z, w) with SqrtMethod::automatic or split: z is used as z1; z2 is drawn
//     with seed = a 64-bit hash of z's bits (splitmix64 chain) and step 0, so w is a
//     deterministic function of z and, for Gaussian z, has covariance M_r + M_w = M.
//   - SqrtMethod::lanczos / chebyshev / cholesky / eigen: the generic solvers on the full
//     operator (MobilityOperator::do_apply_sqrt), e.g. for comparison as in [PSE] Fig. 6.
//
// Rotation (supports_rotation): the grand mobility [U; W] = M [F; T] with the same splitting
// (docs/theory/pse.md Sec. 5): the wave part spreads forces and torques and transforms six
// components each way; the real part adds the rotational blocks' tabulated coefficients over the
// same neighbour lists (the table is built on the first product with torques, ~0.2 s).
// apply_sqrt_rotation with SqrtMethod::automatic or split is the split sampler on the 6N operator:
// Lanczos on S M_r S (S = diag(I, a I), as MobilityOperator::apply_sqrt_rotation) with
// z = [z_t; z_r], plus the wave part's noise from the translational field z2 keyed by the hash of
// z, so that its translational part equals apply_sqrt's wave noise for the same key.
//
// Requirements: periodic geometry (open rejected), equal radii (PSE's assumption; unequal
// radii -> ErrorCode::not_supported). Positions outside the box are wrapped into [0, L)
// (MobilityOperator::set_positions). Parameters are chosen from PseOptions on the first
// set_positions (and again whenever the radius changes, or N changes with automatic xi).
// The apply methods reuse internal work buffers: one operator must not be applied from
// several threads at once (it parallelises internally with OpenMP).
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

class PseRpy final : public PseOperator {
 public:
  /// Throws rpyfmm::Error for an open geometry, viscosity <= 0, or bad options.
  PseRpy(Geometry geometry, double viscosity, const PseOptions& options = {});
  ~PseRpy() override;

  [[nodiscard]] std::string name() const override { return "pse"; }
  [[nodiscard]] const PseOptions& options() const;
  /// The choices made for the current radius/box/N (throws before set_positions).
  [[nodiscard]] const PseParameters& parameters() const override;

  /// U = M_r F (real-space part only), 3N each.
  void apply_real(std::span<const double> forces, std::span<double> velocities) const;
  /// U = M_w F (wave-space part only), 3N each.
  void apply_wave(std::span<const double> forces, std::span<double> velocities) const;
  /// The parts as linear operators (dense assembly, square roots, tests).
  [[nodiscard]] LinearOperatorView real_space_operator() const;
  [[nodiscard]] LinearOperatorView wave_space_operator() const;

  /// w = M^{1/2} z by the split sampler with z1, z2 keyed by (seed, step) (see above).
  SqrtReport sample(std::uint64_t seed, std::uint64_t step, std::span<double> w) const override;
  /// U = M F + noise_scale M^{1/2} z (one fused wave-space pass: the deterministic and the
  /// Brownian wave parts share their FFTs, [PSE] Sec. III). For BD: noise_scale = sqrt(2 kT / dt).
  SqrtReport apply_with_noise(std::span<const double> forces, double noise_scale, std::uint64_t seed,
                              std::uint64_t step, std::span<double> velocities) const override;

  /// Accumulated wall-clock seconds per stage: spread, fft_forward, scale, fft_backward,
  /// interpolate, real_space, lanczos (Lanczos includes its real-space products), plan (parameters,
  /// tables, FFT plans), positions_real (cell order, neighbour lists) and positions_wave (window
  /// weights, tile order) of set_positions.
  [[nodiscard]] StageTimes stage_times() const override;
  void reset_stage_times() const override;

  [[nodiscard]] bool supports_rotation() const override { return true; }

 protected:
  void on_positions_set() override;
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

/// 64-bit hash of the bit patterns of z (the seed of the wave noise in apply_sqrt).
std::uint64_t noise_hash(std::span<const double> z);

}  // namespace rpyfmm::rpy::pse
