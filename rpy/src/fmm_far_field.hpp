// The far field of FmmRpy: the Laplace densities handed to one multi-density FMM pass and the
// velocities (and, with rotation, angular velocities) combined from its results
// (docs/theory/rpy.md, sections 3 and 7; Guan, dissertation, §3.1.1 and Algorithm 2).
#pragma once

#include <cstddef>
#include <span>
#include <vector>

namespace rpyfmm::rpy::detail {

/// Laplace densities per right-hand side of the translational far field: 4 for equal radii, 7 otherwise.
[[nodiscard]] constexpr std::size_t translation_densities(bool equal) noexcept {
  return equal ? 4 : 7;
}
/// Densities of the far field with rotation (one right-hand side): the translational ones and the
/// three torque components.
[[nodiscard]] constexpr std::size_t rotation_densities(bool equal) noexcept {
  return translation_densities(equal) + 3;
}

/// The translational densities of nrhs force vectors: F^(1..3) (potential, gradient, and grad div
/// of the group, fmm::grad_div), x.F (gradient) and for different radii a^2 F^(1..3) (grad div of
/// the group): the far field uses the groups' Hessians only through grad div (docs/theory/rpy.md,
/// section 3). charges: nd x n, outputs: nd, with nd = translation_densities(equal) * nrhs.
void far_field_charges(const double* forces, std::size_t n, std::size_t nrhs, bool equal, std::span<const double> x,
                       std::span<const double> a, std::vector<double>& charges, std::vector<unsigned>& outputs);

/// Velocities (3n per right-hand side, overwritten) from the results of far_field_charges.
void combine_far_field(const std::vector<double>& results, std::size_t n, std::size_t nrhs, bool equal,
                       std::span<const double> x, std::span<const double> a, double eta, double* velocities);

/// The densities of one force and torque pair: far_field_charges' for the forces,
/// then T^(1..3) (curl and grad div, fmm::curl_grad_div). charges: rotation_densities(equal) x n.
void rotation_far_field_charges(const double* forces, const double* torques, std::size_t n, bool equal,
                                std::span<const double> x, std::span<const double> a, std::vector<double>& charges,
                                std::vector<unsigned>& outputs);

/// The rotational far-field sums, times eta and grouped by the power of length they carry:
/// ut = curl Phi_T / (8 pi) (velocities from torques), wf = curl Phi_F / (8 pi) (angular
/// velocities from forces), rr = grad div Phi_T / (16 pi) (angular velocities from torques);
/// 3n each, overwritten. results: of rotation_far_field_charges' densities.
void combine_rotation_far_field(const std::vector<double>& results, std::size_t n, bool equal, double* ut, double* wf,
                                double* rr);

}  // namespace rpyfmm::rpy::detail
