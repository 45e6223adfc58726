// rpyfmm::bd — inertial (Langevin) dynamics of spheres with free-draining friction:
//     m dv = F dt - gamma v dt + sqrt(2 gamma kT) dW,   dx = v dt,   gamma = 6 pi eta a.
//
// Integrator: Gronbech-Jensen & Farago (Mol. Phys. 111, 983 (2013)) with the half-step velocity
// of Jensen & Gronbech-Jensen (Mol. Phys. 117, 2511 (2019)), written per component as
//     v_{n+1/2} = a v_{n-1/2} + (sqrt(b) dt / m) F_n + (sqrt(b) / (2m)) (beta_n + beta_{n+1}),
//     x_{n+1}   = x_n + sqrt(b) dt v_{n+1/2},
// with b = 1 / (1 + gamma dt / 2m), a = (1 - gamma dt / 2m) b and beta_k ~ N(0, 2 gamma kT dt) the
// noise of step k. Chosen because, for every dt in the stable range and every gamma dt / m (the
// paper's step puts small silica at gamma dt / m >> 1 and large alumina near 1), it keeps:
//   - the Boltzmann distribution of positions in a harmonic well exactly (GJF 2013, Sec. 3);
//   - the long-time diffusion coefficient kT / gamma of a free particle exactly;
//   - the kinetic temperature <m v^2> = kT of the half-step velocity exactly (JGJ 2019);
// where BAOAB keeps the first and Euler-type schemes none at gamma dt / m ~ 10. It needs one force
// evaluation per step and no stored noise: beta_n is drawn again from its counter-based key.
//
// Noise: beta_k of particle i, component c is sqrt(2 gamma_i kT dt) normal3(seed, k, stream 4, i)[c]
// (rpy/random.hpp), so a run restarts bit for bit from (x, v_{n-1/2}, n) and is independent of the
// thread count.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

namespace rpyfmm::bd {

/// The Philox stream of the Langevin noise (0: translation, 3: rotation, see integrator.hpp).
inline constexpr std::uint32_t kLangevinNoiseStream = 4;

/// Per-particle mass and friction of inertial particles.
struct LangevinParticle {
  double mass;      ///< > 0
  double friction;  ///< gamma > 0 (6 pi eta a for a sphere)
};

/// Mass of a sphere of radius a and density rho: (4/3) pi a^3 rho.
double sphere_mass(double radius, double density);

/// One GJF step for a set of inertial particles (the header): updates x (3n) and v (3n, the
/// half-step velocities v_{n-1/2} -> v_{n+1/2}) from the forces F_n at x (3n). `step` is n, the
/// index of the step taken (beta_n and beta_{n+1} use keys n and n + 1). `index` gives each
/// particle's noise key (its index in the whole system), so that the noise of a particle does not
/// depend on which others are inertial. Throws rpyfmm::Error on sizes, dt <= 0, kT < 0 or a
/// non-positive mass or friction.
struct LangevinStep {
  double dt;
  double kT;
  std::uint64_t seed;
  std::uint64_t step;
};
void langevin_step(const LangevinStep& s, std::span<const LangevinParticle> particles,
                   std::span<const std::uint64_t> index, std::span<const double> forces, std::span<double> x,
                   std::span<double> v);

/// Velocities drawn from the Maxwell distribution, v_c = sqrt(kT / m) normal3(seed, 0, stream 5, index)
/// (the initial v_{-1/2}).
void maxwell_velocities(double kT, std::uint64_t seed, std::span<const LangevinParticle> particles,
                        std::span<const std::uint64_t> index, std::span<double> v);

}  // namespace rpyfmm::bd
