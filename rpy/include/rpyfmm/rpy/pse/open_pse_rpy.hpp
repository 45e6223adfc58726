// rpyfmm — the RPY mobility in free space (open boundaries) by Positively Split Ewald with a
// compactly supported wave-space kernel (docs/theory/pse.md, "Open boundaries").
//
//   M = M_r + M_w' + c (1 1^T (x) I),   c = 1 / (4 pi eta R),
//   - M_r: the real-space part of PSE (Fiore et al. 2017, App. A), without images;
//   - M_w': PSE's wave-space part computed on a periodic grid whose Stokeslet comes from Askey's
//     compactly supported positive-definite function (1 - r/R)_+^2 in place of the biharmonic
//     kernel r: its multiplier is PSE's times q(kR) >= 0 (PSD), it vanishes beyond R plus the
//     Gaussian's reach, and it equals the free-space wave part minus c I at every pair distance
//     below R minus that reach;
//   - c (1 1^T (x) I): the constant the quadratic term of the Askey function leaves, a common
//     translation of all particles (rank 3, PSD).
// R = D + w with D the diameter of the particles' bounding sphere and w = r_cut + 2a, and the
// periodic box L_d = s_d + R + w (s_d: the particles' extent along d), so that no periodic image
// comes within reach. D and s_d are rounded up to steps of 2^(1/16) (4.4%) so that the plan (box,
// grid, xi) is reused while the configuration's extent stays within a step: it is a function of
// the configuration alone (the same positions give the same plan and the same results, bit for
// bit, whatever came before).
//
// Brownian noise: the split sampler of PseRpy on M_r + M_w', plus sqrt(c) zeta on every particle,
// zeta = normal3(seed, step, stream 6, 0) (sample / apply_with_noise) or, for apply_sqrt, keyed by
// the hash of z as PseRpy's wave noise. So one Brownian displacement costs about one product
// (docs/theory/pse.md): no Krylov iterations on the full operator.
//
// Requirements: open geometry, equal radii (PSE's assumption; unequal radii -> not_supported). The
// grid covers 8 (a ball of particles) to 20 (a cube) times the volume of the particles' bounding
// box, plus the margins w: configurations spread over very large distances (far-apart clusters) need
// large grids and fail with out_of_memory beyond PseOptions::max_memory_bytes; the FMM operator
// suits them. Rotation is supported as in PseRpy (the constant c enters U only: the rotational
// blocks are curls of the kernel). The CUDA backend does not offer open boundaries yet.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/rpy/pse/pse_operator.hpp"
#include "rpyfmm/rpy/pse/pse_parameters.hpp"

namespace rpyfmm::rpy::pse {

class OpenPseRpy final : public PseOperator {
 public:
  /// Throws rpyfmm::Error for viscosity <= 0 or bad options (tolerance as PseOptions; the
  /// open_truncation and pair_density fields are set by this operator and must be 0).
  explicit OpenPseRpy(double viscosity, const PseOptions& options = {});
  ~OpenPseRpy() override;

  [[nodiscard]] std::string name() const override { return "pse-open"; }
  [[nodiscard]] const PseOptions& options() const;
  /// The choices of the current plan (xi, grid, ..., open_truncation = R); throws before set_positions.
  [[nodiscard]] const PseParameters& parameters() const override;
  /// The periodic box L of the current plan (throws before set_positions).
  [[nodiscard]] std::array<double, 3> box() const;
  /// The constant c = 1 / (4 pi eta R) of the current plan (throws before set_positions).
  [[nodiscard]] double constant_part() const;

  SqrtReport sample(std::uint64_t seed, std::uint64_t step, std::span<double> w) const override;
  SqrtReport apply_with_noise(std::span<const double> forces, double noise_scale, std::uint64_t seed,
                              std::uint64_t step, std::span<double> velocities) const override;
  /// PseRpy's stages, plus plan (choosing xi and the box, FFT plans) and shift (positions into the box).
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

}  // namespace rpyfmm::rpy::pse
