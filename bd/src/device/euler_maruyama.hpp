// rpyfmm::bd::device — one particle's free-draining Euler-Maruyama step (Tran et al. (2015),
// eq. 3; docs/theory/bd.md):
//
//     dx = mu F dt + sqrt(2 kT dt) sqrt(mu) z,   mu = 1 / (6 pi eta a),  z = brownian_normals
//
// with the blow-up guard of Integrator::checked_displacements (a step moving a particle more than
// max_displacement x its radius, or not finite, is refused), and, as the update kernel of
// Tran et al. (2015) does (Algorithm 1, lines 14-16), the rebuild test of the next step on the new position.
// Positions stay unwrapped, as in the CPU engine (mean-square displacements); the minimum image
// is taken where pairs are measured (minimum_image.hpp) and the wrap where particles are binned
// (cell_binning.hpp). The operations of the CPU engine's step, in its order.
//
// With hydrodynamic interactions (PSE, docs/gpu-bd.md) the step's velocities come from one
// product U = M F + sqrt(2 kT dt) / dt M^{1/2} z (Fiore et al. (2017), eq. 5 and Sec. III), and
// dx = U dt (advance_particle_with), with the same guard and rebuild test.
#pragma once

#include <cstdint>

#include "atomics.hpp"
#include "brownian_noise.hpp"
#include "rebuild_test.hpp"
#include "rpyfmm/core/host_device.hpp"

namespace rpyfmm::bd::device {

/// The per-type mobilities and the step's constants.
struct MotionTables {
  const std::uint32_t* type = nullptr;    ///< per particle
  const double* mobility = nullptr;       ///< per type: 1 / (6 pi eta a)
  const double* sqrt_mobility = nullptr;  ///< per type: its square root
  const double* radius = nullptr;         ///< per type
  double dt = 0.0;
  double noise = 0.0;              ///< sqrt(2 kT dt)
  bool brownian = false;           ///< kT > 0
  double max_displacement2 = 1.0;  ///< (max_displacement)^2, in radii
  std::uint64_t seed = 0;
  std::uint64_t step = 0;
};

/// Where a step goes: the new positions (kept only when no particle failed the guard), the
/// positions of the last list build, and the store_min slots of the lowest particle refused by
/// the guard and the lowest one beyond skin/2 (limit2 = (skin/2)^2; 0 slots: no list).
struct MotionOutput {
  double* x_next = nullptr;
  const double* reference = nullptr;
  double limit2 = 0.0;
  std::uint64_t* bad_move = nullptr;
  std::uint64_t* moved = nullptr;
};

/// False when the guard refuses a displacement of squared length d2 of particle i (NaN too).
RPYFMM_HOST_DEVICE inline bool within_guard(std::uint32_t i, double d2, const MotionTables& m) {
  const std::uint32_t t = m.type[i];
  return d2 <= m.max_displacement2 * m.radius[t] * m.radius[t];
}

/// dx of particle i from its force f (3 per particle) and its noise z (ignored without Brownian
/// motion); false when the guard refuses it.
RPYFMM_HOST_DEVICE inline bool displacement_with(std::uint32_t i, const double z[3], const double* f,
                                                 const MotionTables& m, double dx[3]) {
  const std::uint32_t t = m.type[i];
  double d2 = 0.0;
  for (int c = 0; c < 3; ++c) {
    const double u = m.mobility[t] * f[3 * static_cast<std::uint64_t>(i) + c];
    const double w = m.sqrt_mobility[t] * z[c];
    const double d = u * m.dt + (m.brownian ? m.noise * w : 0.0);
    dx[c] = d;
    d2 += d * d;
  }
  return within_guard(i, d2, m);
}

/// dx = U dt of particle i from the velocities u (3 per particle); false when the guard refuses
/// it. The "+ 0.0" is Integrator::checked_displacements' sum with its Brownian term absent (the
/// noise is inside U), so that a -0 rounds as there.
RPYFMM_HOST_DEVICE inline bool displacement_from_velocity(std::uint32_t i, const double* u, const MotionTables& m,
                                                          double dx[3]) {
  double d2 = 0.0;
  for (int c = 0; c < 3; ++c) {
    const double d = u[3 * static_cast<std::uint64_t>(i) + c] * m.dt + 0.0;
    dx[c] = d;
    d2 += d * d;
  }
  return within_guard(i, d2, m);
}

/// dx of particle i of the whole system, its noise drawn from its index.
RPYFMM_HOST_DEVICE inline bool displacement(std::uint32_t i, const double* f, const MotionTables& m, double dx[3]) {
  double z[3] = {0.0, 0.0, 0.0};
  if (m.brownian) brownian_normals(m.seed, m.step, i, z);
  return displacement_with(i, z, f, m, dx);
}

/// x_next = x + dx for particle i (allowed: the guard's verdict) and the next step's rebuild test.
RPYFMM_HOST_DEVICE inline void move_particle(std::uint32_t i, const double* x, const double dx[3], bool allowed,
                                             const MotionOutput& out) {
  if (!allowed) store_min(out.bad_move, i);
  const std::uint64_t k = 3 * static_cast<std::uint64_t>(i);
  for (int c = 0; c < 3; ++c) out.x_next[k + c] = x[k + c] + dx[c];
  if (out.reference != nullptr && moved_beyond_half_skin(i, out.x_next, out.reference, out.limit2))
    store_min(out.moved, i);
}

/// Free draining: x_next = x + mu F dt + sqrt(2 kT dt) sqrt(mu) z for particle i, the guard and
/// the next step's rebuild test.
RPYFMM_HOST_DEVICE inline void advance_particle(std::uint32_t i, const double* x, const double* f,
                                                const MotionTables& m, const MotionOutput& out) {
  double dx[3];
  const bool allowed = displacement(i, f, m, dx);
  move_particle(i, x, dx, allowed, out);
}

/// Hydrodynamic interactions: x_next = x + U dt for particle i from the velocities u of the
/// step's mobility product, the guard and the next step's rebuild test.
RPYFMM_HOST_DEVICE inline void advance_particle_with(std::uint32_t i, const double* x, const double* u,
                                                     const MotionTables& m, const MotionOutput& out) {
  double dx[3];
  const bool allowed = displacement_from_velocity(i, u, m, dx);
  move_particle(i, x, dx, allowed, out);
}

}  // namespace rpyfmm::bd::device
