// rpyfmm — the one mobility interface: U = M F for N spheres.
//
// Every solver (direct, FMM, PSE CPU, PSE CUDA) implements this class. The
// public methods validate their input once (non-virtual interface) and then
// call the solver's protected hooks, so no solver repeats validation.
//
// Conventions: positions, forces and velocities are flat arrays of length 3N,
// particle-major (x0, y0, z0, x1, ...). Several right-hand sides ("block")
// are stored one 3N vector after another. Units are the caller's: with
// viscosity eta and radius a, M_ii = 1/(6 pi eta a).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "rpyfmm/rpy/geometry.hpp"
#include "rpyfmm/rpy/sqrt.hpp"

namespace rpyfmm::rpy {

class MobilityOperator {
 public:
  virtual ~MobilityOperator() = default;
  MobilityOperator(const MobilityOperator&) = delete;
  MobilityOperator& operator=(const MobilityOperator&) = delete;

  /// Short solver name ("direct", "fmm", "pse", "pse-cuda").
  [[nodiscard]] virtual std::string name() const = 0;

  [[nodiscard]] const Geometry& geometry() const { return geometry_; }
  [[nodiscard]] double viscosity() const { return viscosity_; }
  /// Number of particles N (0 before set_positions).
  [[nodiscard]] std::size_t size() const { return radii_.size(); }
  /// The positions of the last set_positions, wrapped into the box in a periodic geometry. After
  /// an operator moved its particles on a device (PseRpyCuda::set_positions_device) they are copied
  /// from there on the first read.
  [[nodiscard]] std::span<const double> positions() const;
  [[nodiscard]] std::span<const double> radii() const { return radii_; }
  /// True when every particle has the same radius (the solvers' fast path).
  [[nodiscard]] bool equal_radii() const { return equal_radii_; }

  /// Sets positions (3N) and one common radius. Builds the solver's plan
  /// (tree, lists, cells, FFT plans) once; apply() may then be called many times.
  /// Throws rpyfmm::Error on N = 0, size not a multiple of 3, NaN/Inf, radius <= 0.
  /// In a periodic geometry positions are wrapped into [0, L). When planning fails
  /// (e.g. PSE: box smaller than 2 r_cut) the error propagates and the operator holds
  /// no positions until a later set_positions succeeds (products then throw, never crash).
  void set_positions(std::span<const double> positions, double radius);
  /// Same with per-particle radii (N entries, each finite, > 0 and normal).
  void set_positions(std::span<const double> positions, std::span<const double> radii);

  /// U = M F (3N each).
  void apply(std::span<const double> forces, std::span<double> velocities) const;
  /// U_k = M F_k for nrhs right-hand sides stored one after another. Each F_k is load-scaled by its
  /// own power of two, as apply() scales it alone, so a right-hand side's result does not depend on
  /// the magnitude of the others.
  void apply_block(std::span<const double> forces, std::span<double> velocities, std::size_t nrhs) const;

  /// [U; W] = M [F; T]: the grand mobility with rotation (docs/theory/rpy.md, "Rotation"):
  /// velocities U and angular velocities W (3N each) from forces F and torques T (3N each).
  /// Throws rpyfmm::Error (not_supported) unless supports_rotation(); sizes and finiteness as
  /// for apply().
  void apply(std::span<const double> forces, std::span<const double> torques, std::span<double> velocities,
             std::span<double> angular_velocities) const;
  /// True when the four-argument apply (torques, angular velocities) is available.
  [[nodiscard]] virtual bool supports_rotation() const { return false; }

  /// w = M^{1/2} z (3N each), by the method in `options` (default: the
  /// operator's preferred one, Lanczos unless the solver overrides it).
  SqrtReport apply_sqrt(std::span<const double> z, std::span<double> w, const SqrtOptions& options = {}) const;
  /// Block version: nrhs noise vectors at once.
  SqrtReport apply_sqrt_block(std::span<const double> z, std::span<double> w, std::size_t nrhs,
                              const SqrtOptions& options = {}) const;

  /// [w_t; w_r] = B [z_t; z_r] with B B^T = the grand mobility (rotation; 3N each), the Brownian
  /// displacements and rotations of a step with rotational diffusion (docs/theory/samplers.md, "Rotation").
  /// The samplers run on the scaled grand mobility S M S, S = diag(I_3N, diag(a_i) (x) I_3): its self
  /// blocks are 1 / (6 pi eta a_i) and 1 / (8 pi eta a_i), of one magnitude, so the tolerance means
  /// the same for translation and rotation. The result is B z = S^{-1} (S M S)^{1/2} z (covariance M),
  /// which is M^{1/2} z when all radii are 1; a Lanczos / Chebyshev tolerance bounds the error
  /// relative to |S B z|, i.e. with the rotations weighted by a_i. Methods and options as apply_sqrt:
  /// automatic = the operator's own exact sampler where it has one (free draining), Lanczos otherwise;
  /// `block` factors 6 x 6 per-particle blocks of S M S within each spatial block; cholesky / eigen
  /// work up to 6N = kDenseSqrtMaxRows rows; split is not_supported.
  /// Throws rpyfmm::Error (not_supported) unless supports_rotation(); sizes and finiteness as for
  /// apply_sqrt.
  SqrtReport apply_sqrt_rotation(std::span<const double> z_translation, std::span<const double> z_rotation,
                                 std::span<double> w_translation, std::span<double> w_rotation,
                                 const SqrtOptions& options = {}) const;

  // Capability queries: what an operator offers beyond U = M F, so that callers (the BD
  // engine) choose a path by asking the operator rather than by its name or type.

  /// The method apply_sqrt takes for SqrtMethod::automatic: lanczos on products (the default
  /// do_apply_sqrt), split for PSE, cholesky for the exact diagonal of free draining. An
  /// operator that overrides do_apply_sqrt overrides this too.
  [[nodiscard]] virtual SqrtMethod native_sampler() const { return SqrtMethod::lanczos; }
  /// True when apply_with_noise gives the drift and the Brownian velocity in one pass (PSE: the
  /// deterministic and Brownian wave-space parts share their FFTs, docs/theory/pse.md).
  [[nodiscard]] virtual bool fuses_drift_and_noise() const { return false; }
  /// U = M F + noise_scale M^{1/2} z in one pass, with the operator's own noise keyed by
  /// (seed, step). For BD: noise_scale = sqrt(2 kT / dt). Throws not_supported unless
  /// fuses_drift_and_noise().
  virtual SqrtReport apply_with_noise(std::span<const double> forces, double noise_scale, std::uint64_t seed,
                                      std::uint64_t step, std::span<double> velocities) const;

  /// Divergence of M with respect to the positions (3N); zero for RPY.
  virtual void divergence(std::span<double> out) const;

  /// Dense 3N x 3N matrix, row-major, assembled from products with unit vectors
  /// (small N only: throws if 9 N^2 doubles exceed `max_bytes`).
  [[nodiscard]] std::vector<double> assemble_dense(std::size_t max_bytes = std::size_t{1} << 31) const;

  /// This operator as a plain linear operator (for the square-root solvers).
  [[nodiscard]] LinearOperatorView as_linear_operator() const;

 protected:
  /// `where` names the concrete class in error messages.
  MobilityOperator(Geometry geometry, double viscosity, const char* where);

  /// Called after positions/radii have been validated and stored.
  virtual void on_positions_set() = 0;
  /// U = M F for nrhs right-hand sides; sizes already checked.
  virtual void do_apply(const double* forces, double* velocities, std::size_t nrhs) const = 0;
  /// [U; W] = M [F; T] (3N each); sizes already checked. Default: not_supported.
  virtual void do_apply_rotation(const double* forces, const double* torques, double* velocities,
                                 double* angular_velocities) const;
  /// Default: generic solvers on apply() (Lanczos for `automatic`).
  virtual SqrtReport do_apply_sqrt(std::span<const double> z, std::span<double> w, std::size_t nrhs,
                                   const SqrtOptions& options) const;
  /// [w_t; w_r] = S^{-1} (S M S)^{1/2} [z_t; z_r] (3N each, see apply_sqrt_rotation); sizes and
  /// rotation support already checked. Default: the generic solvers on do_apply_rotation (Lanczos
  /// for `automatic`).
  virtual SqrtReport do_apply_sqrt_rotation(std::span<const double> z_translation, std::span<const double> z_rotation,
                                            std::span<double> w_translation, std::span<double> w_rotation,
                                            const SqrtOptions& options) const;

  /// Throws unless N > 0 (called before every apply).
  void require_positions(const char* where) const;

  /// The operator placed the same particles at new positions held elsewhere (a device): the host
  /// copy is out of date until positions() asks read_positions() for it.
  void mark_positions_moved() { positions_moved_ = true; }
  /// Writes the current positions (3N, wrapped into the box) into `out`. Called by positions()
  /// after mark_positions_moved(); the default throws (no operator moves its particles but
  /// through set_positions unless it overrides this).
  virtual void read_positions(std::vector<double>& out) const;

 private:
  /// S M S with rotation as a 6N operator on [x_t; x_r] (apply_sqrt_rotation's scaling).
  [[nodiscard]] LinearOperatorView scaled_grand_operator() const;
  void store_positions(std::span<const double> positions, std::span<const double> radii, bool equal);

  Geometry geometry_;
  double viscosity_;
  std::string where_;
  mutable std::vector<double> positions_;  // refreshed by positions() after mark_positions_moved()
  mutable bool positions_moved_ = false;
  std::vector<double> radii_;
  bool equal_radii_ = true;
};

}  // namespace rpyfmm::rpy
