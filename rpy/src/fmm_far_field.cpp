// The far field of FmmRpy (fmm_far_field.hpp).
#include "fmm_far_field.hpp"

#include <cstdint>
#include <numbers>

#include "rpyfmm/fmm/laplace_fmm.hpp"

namespace rpyfmm::rpy::detail {
namespace {
constexpr double pi = std::numbers::pi;
}  // namespace

// The Laplace densities of the far field (docs/theory/rpy.md; Guan, dissertation, Algorithm 2),
// per right-hand side: F^(1..3) (potential, field, grad div), x.F (field) and for different radii
// a^2 F^(1..3) (grad div). charges: nd x n, outputs: nd.
void far_field_charges(const double* forces, std::size_t n, std::size_t nrhs, bool equal, std::span<const double> x,
                       std::span<const double> a, std::vector<double>& charges, std::vector<unsigned>& outputs) {
  const std::size_t per_rhs = translation_densities(equal);
  for (std::size_t k = 0; k < nrhs; ++k) {
    const double* f = forces + 3 * n * k;
    double* q = charges.data() + per_rhs * n * k;
    for (std::size_t m = 0; m < 3; ++m) {
      outputs[per_rhs * k + m] = fmm::potential | fmm::gradient | fmm::grad_div;
      for (std::size_t j = 0; j < n; ++j) q[m * n + j] = f[3 * j + m];
    }
    outputs[per_rhs * k + 3] = fmm::gradient;
    for (std::size_t j = 0; j < n; ++j) {
      const double* xj = &x[3 * j];
      q[3 * n + j] = xj[0] * f[3 * j] + xj[1] * f[3 * j + 1] + xj[2] * f[3 * j + 2];
    }
    if (!equal) {
      for (std::size_t m = 0; m < 3; ++m) {
        outputs[per_rhs * k + 4 + m] = fmm::grad_div;
        for (std::size_t j = 0; j < n; ++j) q[(4 + m) * n + j] = a[j] * a[j] * f[3 * j + m];
      }
    }
  }
}

namespace {

// -(grad div Phi)_c at target i of the group of three densities from `first` (T = -H): the folded
// sum in the group's first row (fmm::grad_div).
double minus_grad_div(const double* r, std::size_t first, std::size_t n, std::size_t i, int c) {
  return -r[(first * n + i) * 10 + 4 + c];
}

}  // namespace

// The far-field velocities from the FMM results of far_field_charges (the formula in
// fmm_operator.hpp; docs/theory/rpy.md; Guan, dissertation, §3.1.1); E = -g, T = -H, and the
// dipole terms sum_m T_cm(F^m) = -(grad div Phi_F)_c.
void combine_far_field(const std::vector<double>& results, std::size_t n, std::size_t nrhs, bool equal,
                       std::span<const double> x, std::span<const double> a, double eta, double* velocities) {
  const std::size_t per_rhs = translation_densities(equal);
  const double c1 = 1.0 / (8.0 * pi * eta);
  const double c2 = 1.0 / (24.0 * pi * eta);
  const auto nn = static_cast<std::int64_t>(n);
  for (std::size_t k = 0; k < nrhs; ++k) {
    const double* r = results.data() + per_rhs * n * 10 * k;
    double* u = velocities + 3 * n * k;
#pragma omp parallel for schedule(static)
    for (std::int64_t ii = 0; ii < nn; ++ii) {
      const auto i = static_cast<std::size_t>(ii);
      const double* xi = &x[3 * i];
      const double ai2 = a[i] * a[i];
      const double* rxF = r + (3 * n + i) * 10;  // results of x.F at target i
      for (int c = 0; c < 3; ++c) {
        double oseen = r[(c * n + i) * 10];                                        // phi(F^(c))
        for (int m = 0; m < 3; ++m) oseen -= xi[m] * r[(m * n + i) * 10 + 1 + c];  // + x_m E_c(F^m), E = -g
        oseen += rxF[1 + c];                                                       // - E_c(x.F)
        const double dipole = minus_grad_div(r, 0, n, i, c);                       // sum_m T_cm(F^m)
        double value = c1 * oseen + c2 * ai2 * dipole;
        if (equal) {
          value += c2 * ai2 * dipole;  // a_j^2 = a_i^2
        } else {
          value += c2 * minus_grad_div(r, 4, n, i, c);  // sum_m T_cm(a^2 F^m)
        }
        u[3 * i + c] = value;
      }
    }
  }
}

void rotation_far_field_charges(const double* forces, const double* torques, std::size_t n, bool equal,
                                std::span<const double> x, std::span<const double> a, std::vector<double>& charges,
                                std::vector<unsigned>& outputs) {
  const std::size_t base = translation_densities(equal);
  far_field_charges(forces, n, 1, equal, x, a, charges, outputs);
  for (std::size_t m = 0; m < 3; ++m) {
    outputs[base + m] = fmm::curl_grad_div;
    double* q = charges.data() + (base + m) * n;
    for (std::size_t j = 0; j < n; ++j) q[j] = torques[3 * j + m];
  }
}

// With phi_k = sum_j q_j,k / |x - x_j| and g(k)_m = d_m phi_k (the FMM's gradient column 1 + m):
// (curl Phi)_c = g(c+2)_(c+1) - g(c+1)_(c+2) (indices mod 3); curl Phi_T and grad div Phi_T come
// from the FMM (fmm::curl_grad_div) in the first torque row, columns 1..3 and 4..6
// (docs/theory/rpy.md, section 7).
void combine_rotation_far_field(const std::vector<double>& results, std::size_t n, bool equal, double* ut, double* wf,
                                double* rr) {
  const std::size_t torque0 = translation_densities(equal);
  const double c_curl = 1.0 / (8.0 * pi), c_grad_div = 1.0 / (16.0 * pi);
  const auto nn = static_cast<std::int64_t>(n);
#pragma omp parallel for schedule(static)
  for (std::int64_t ii = 0; ii < nn; ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    const auto force_row = [&](std::size_t m) { return results.data() + (m * n + i) * 10; };
    const double* torque = results.data() + (torque0 * n + i) * 10;
    for (std::size_t c = 0; c < 3; ++c) {
      const std::size_t c1 = (c + 1) % 3, c2 = (c + 2) % 3;
      ut[3 * i + c] = c_curl * torque[1 + c];
      wf[3 * i + c] = c_curl * (force_row(c2)[1 + c1] - force_row(c1)[1 + c2]);
      rr[3 * i + c] = c_grad_div * torque[4 + c];
    }
  }
}

}  // namespace rpyfmm::rpy::detail
