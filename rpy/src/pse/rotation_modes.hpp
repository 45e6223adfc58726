// rpyfmm — PSE wave-space scaling of one mode for the grand mobility with rotation (docs/theory/pse.md,
// "Rotation"). Pure functions for host and device, like kernels_common.hpp. Private.
//
// With the sphere's translational and rotational shape factors sinc(ka) and s(ka) = 3 j1(ka) / ka,
// a torque acts on the fluid as the force density curl (T / 2) and a sphere turns with half the
// vorticity, each averaged with s over the sphere. Per mode, with C(k) [F; T] = sinc F + (s/2) i k x T,
//     u~ = g(k) P_k C [F; T] + noise_factor sign(sinc) sqrt(g(k)) P_k z(k),
//     U = sinc u~,   W = (s/2) i k x u~,
// g(k) = (1 + k^2/4xi^2) exp(-(1 - eta) k^2/4xi^2) / (k^2 mu Ng) the translational factor without
// sinc^2, P_k = I - khat khat. So the wave part is C^H g P C, positive semi-definite, and its noise
// needs only the translational field z(k): U's noise is the translational sampler's
// (|sinc| sqrt(g) = sqrt(c(k)) of scale_mode_with), and W's follows from the same u~.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

#include "kernels_common.hpp"
#include "open_truncation.hpp"

namespace rpyfmm::rpy::pse::detail {

/// Per-plan constants of g(k) (see above).
struct RotationModeConstants {
  double radius;
  double inv_4xi2;               ///< 1 / (4 xi^2)
  double one_minus_eta;          ///< 1 - window_eta
  double inv_mu_ng;              ///< 1 / (mu Ng)
  double open_truncation = 0.0;  ///< R of the open-boundary kernel (open_truncation.hpp; 0: periodic)
};

/// sinc(x) and s(x) / 2 = 3 j1(x) / (2x); below x = 0.5 from their series (the closed form of s
/// cancels as x -> 0).
RPYFMM_HOST_DEVICE inline void rotation_shape_factors(double x, double& sinc, double& half_s) {
  if (x < 0.5) {
    const double q = -0.5 * x * x;
    double t0 = 1.0, s0 = 1.0, t1 = 1.0, s1 = 1.0;
    for (int m = 1; m < 12; ++m) {
      t0 *= q / (m * (2.0 * m + 1.0));
      t1 *= q / (m * (2.0 * m + 3.0));
      s0 += t0;
      s1 += t1;
    }
    sinc = s0;
    half_s = 0.5 * s1;
    return;
  }
  sinc = std::sin(x) / x;
  half_s = 1.5 * (sinc - std::cos(x)) / (x * x);
}

/// The factors of one mode that depend on |k| only: g(k) (with the open-boundary truncation
/// where rc has one), sinc(ka) and s(ka) / 2. Computed once per plan for every mode
/// (WaveGrid::rotation_factors_), so that a product scales its modes without sin, cos and exp.
struct RotationModeFactors {
  double gk, sinc, half_s;
};

/// The factors of mode (ix, iy, iz); k = 0 gives zeros (that mode is cleared, scale_rotation_mode).
RPYFMM_HOST_DEVICE inline RotationModeFactors rotation_mode_factors(int ix, int iy, int iz, const ModeGeometry& g,
                                                                    const RotationModeConstants& rc) {
  const double k[3] = {g.two_pi_L[0] * signed_index(ix, g.n[0]), g.two_pi_L[1] * signed_index(iy, g.n[1]),
                       g.two_pi_L[2] * iz};
  const double k2 = k[0] * k[0] + k[1] * k[1] + k[2] * k[2];
  if (k2 == 0.0) return {0.0, 0.0, 0.0};
  RotationModeFactors m{};
  rotation_shape_factors(std::sqrt(k2) * rc.radius, m.sinc, m.half_s);
  const double q = k2 * rc.inv_4xi2;
  m.gk = (1.0 + q) * std::exp(-rc.one_minus_eta * q) / k2 * rc.inv_mu_ng;
  if (rc.open_truncation > 0.0) m.gk *= open_truncation_factor(std::sqrt(k2) * rc.open_truncation);
  return m;
}

/// Scales mode (ix, iy, iz), linear half-spectrum index idx, of the force spectrum `fs` and the
/// torque spectrum `ts` in place: on return they hold U and W (see above). Layout, noise and
/// representative as scale_mode_with; `ck` is the translational table (zero marks k = 0 and the
/// Nyquist planes), `m` the mode's rotation_mode_factors. deterministic = false: the spectra are
/// overwritten with the noise alone.
template <class Real, class Noise>
RPYFMM_HOST_DEVICE inline void scale_rotation_mode(int ix, int iy, int iz, std::size_t idx, const ModeGeometry& g,
                                                   const double* ck, const RotationModeFactors& m, Real* fs, Real* ts,
                                                   bool deterministic, const Noise* z, bool representative,
                                                   double noise_factor) {
  Real* f[3] = {fs + 2 * idx, fs + 2 * idx + g.comp_stride, fs + 2 * idx + 2 * g.comp_stride};
  Real* t[3] = {ts + 2 * idx, ts + 2 * idx + g.comp_stride, ts + 2 * idx + 2 * g.comp_stride};
  if (ck[idx] == 0.0) {
    for (int d = 0; d < 3; ++d) f[d][0] = f[d][1] = t[d][0] = t[d][1] = Real(0);
    return;
  }
  const double k[3] = {g.two_pi_L[0] * signed_index(ix, g.n[0]), g.two_pi_L[1] * signed_index(iy, g.n[1]),
                       g.two_pi_L[2] * iz};
  const double k2 = k[0] * k[0] + k[1] * k[1] + k[2] * k[2];
  const double gk = m.gk, sinc = m.sinc, half_s = m.half_s;
  const auto cross = [&k](const double* v, int d) {
    const int d1 = (d + 1) % 3, d2 = (d + 2) % 3;
    return k[d1] * v[d2] - k[d2] * v[d1];
  };
  double re[3] = {0.0, 0.0, 0.0}, im[3] = {0.0, 0.0, 0.0};
  if (deterministic) {
    // C [F; T] = sinc F + (s/2) i k x T:  re = sinc Re F - (s/2) k x Im T,  im = sinc Im F + (s/2) k x Re T.
    const double tr[3] = {t[0][0], t[1][0], t[2][0]};
    const double ti[3] = {t[0][1], t[1][1], t[2][1]};
    for (int d = 0; d < 3; ++d) {
      re[d] = gk * (sinc * f[d][0] - half_s * cross(ti, d));
      im[d] = gk * (sinc * f[d][1] + half_s * cross(tr, d));
    }
  }
  if (z != nullptr) {
    // As scale_mode_with, with sqrt(c) = |sinc| sqrt(g) split into sign(sinc) sqrt(g) here and sinc below.
    const double amp = (sinc < 0.0 ? -noise_factor : noise_factor) * std::sqrt(gk) * 0.70710678118654752440;
    const double sgn = representative ? amp : -amp;
    for (int d = 0; d < 3; ++d) {
      re[d] += amp * z[d];
      im[d] += sgn * z[3 + d];
    }
  }
  const double pr = (k[0] * re[0] + k[1] * re[1] + k[2] * re[2]) / k2;
  const double pim = (k[0] * im[0] + k[1] * im[1] + k[2] * im[2]) / k2;
  for (int d = 0; d < 3; ++d) {
    re[d] -= k[d] * pr;
    im[d] -= k[d] * pim;
  }
  // U = sinc u~;  W = (s/2) i k x u~:  Re W = -(s/2) k x Im u~,  Im W = (s/2) k x Re u~.
  for (int d = 0; d < 3; ++d) {
    f[d][0] = static_cast<Real>(sinc * re[d]);
    f[d][1] = static_cast<Real>(sinc * im[d]);
    t[d][0] = static_cast<Real>(-half_s * cross(im, d));
    t[d][1] = static_cast<Real>(half_s * cross(re, d));
  }
}

/// The mode of linear half-spectrum index idx with its own noise draw, for one GPU thread per mode
/// (as scale_mode for the translational spectrum): the (ix, iy, iz) of idx, normal6 / normal6f
/// (Real = float) of the mode pair's representative under (seed, step, kStreamWave), as
/// WaveGrid::scale_rotation_modes draws them on the CPU, then scale_rotation_mode. `factors` holds
/// rotation_mode_factors per mode, indexed by idx.
template <class Real>
RPYFMM_HOST_DEVICE inline void scale_rotation_mode_at(std::size_t idx, const ModeGeometry& g, const double* ck,
                                                      const RotationModeFactors* factors, Real* fs, Real* ts,
                                                      bool deterministic, bool noise, std::uint64_t seed,
                                                      std::uint64_t step, double noise_factor) {
  int ix, iy, iz;
  half_spectrum_mode(idx, g, ix, iy, iz);
  Real z[6];
  const bool representative = noise ? draw_mode_noise(ix, iy, iz, g, seed, step, z) : true;
  scale_rotation_mode(ix, iy, iz, idx, g, ck, factors[idx], fs, ts, deterministic, noise ? z : nullptr, representative,
                      noise_factor);
}

/// rotation_mode_factors of linear half-spectrum index idx (one GPU thread per mode).
RPYFMM_HOST_DEVICE inline RotationModeFactors rotation_mode_factors_at(std::size_t idx, const ModeGeometry& g,
                                                                       const RotationModeConstants& rc) {
  int ix, iy, iz;
  half_spectrum_mode(idx, g, ix, iy, iz);
  return rotation_mode_factors(ix, iy, iz, g, rc);
}

}  // namespace rpyfmm::rpy::pse::detail
