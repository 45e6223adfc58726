// rpyfmm — DirectRpy's grand mobility with rotation: [U; W] = M [F; T] over all pairs
// (docs/theory/rpy.md, "Rotation"; Wajnryb, Mizerski, Zuk & Szymczak 2013).
//
// Per target i, the sources j in input order: U_i gets M^tt_ij F_j + ut (T_j x e), W_i gets
// wf (F_j x e) + (h I + k e e^T) T_j with the coefficients of rpy_rotation_kernel.hpp. Each target is
// summed by one thread in a fixed order, so results do not depend on the thread count.
#include <cmath>
#include <cstddef>

#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/rpy_kernel.hpp"
#include "rpyfmm/rpy/rpy_rotation_kernel.hpp"

namespace rpyfmm::rpy {
namespace {

struct Vec3 {
  double x, y, z;
};

Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
double dot(const Vec3& a, const Vec3& b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}

/// The four sums of one target, by the powers of length they carry (for the units of
/// length_units.hpp): tt ~ 1/L, ut and wf ~ 1/L^2, rr ~ 1/L^3.
struct TargetSums {
  Vec3 tt{}, ut{}, wf{}, rr{};

  void add(const Vec3& d, double r, double ai, double aj, const Vec3& f, const Vec3& t) {
    const Vec3 e = r > 0.0 ? Vec3{d.x / r, d.y / r, d.z / r} : Vec3{0.0, 0.0, 0.0};
    const RpyScalars s = rpy_scalars(r, ai, aj);
    const RpyRotationScalars q = rpy_rotation_scalars(r, ai, aj);
    const double ef = dot(e, f), et = dot(e, t);
    const Vec3 te = cross(t, e), fe = cross(f, e);
    tt = {tt.x + s.f * f.x + s.g * ef * e.x, tt.y + s.f * f.y + s.g * ef * e.y, tt.z + s.f * f.z + s.g * ef * e.z};
    ut = {ut.x + q.ut * te.x, ut.y + q.ut * te.y, ut.z + q.ut * te.z};
    wf = {wf.x + q.wf * fe.x, wf.y + q.wf * fe.y, wf.z + q.wf * fe.z};
    rr = {rr.x + q.h * t.x + q.k * et * e.x, rr.y + q.h * t.y + q.k * et * e.y, rr.z + q.h * t.z + q.k * et * e.z};
  }
};

}  // namespace

void DirectRpy::do_apply_rotation(const double* forces, const double* torques, double* velocities,
                                  double* angular_velocities) const {
  const std::size_t n = size();
  const double inv_eta = 1.0 / viscosity();
  const int e1 = -scale_exponent_, e2 = -2 * scale_exponent_, e3 = -3 * scale_exponent_;
#pragma omp parallel for schedule(dynamic, 16)
  for (std::size_t i = 0; i < n; ++i) {
    TargetSums sums;
    for (std::size_t j = 0; j < n; ++j) {
      const Vec3 d{x_[i] - x_[j], y_[i] - y_[j], z_[i] - z_[j]};
      const Vec3 f{forces[3 * j], forces[3 * j + 1], forces[3 * j + 2]};
      const Vec3 t{torques[3 * j], torques[3 * j + 1], torques[3 * j + 2]};
      // i == j is the r = 0 limit: 1/(6 pi a) I and 1/(8 pi a^3) I, no coupling.
      sums.add(d, i == j ? 0.0 : std::sqrt(dot(d, d)), a_[i], a_[j], f, t);
    }
    const double u[3] = {sums.tt.x, sums.tt.y, sums.tt.z}, ut[3] = {sums.ut.x, sums.ut.y, sums.ut.z};
    const double wf[3] = {sums.wf.x, sums.wf.y, sums.wf.z}, rr[3] = {sums.rr.x, sums.rr.y, sums.rr.z};
    for (int c = 0; c < 3; ++c) {
      velocities[3 * i + c] = inv_eta * (std::ldexp(u[c], e1) + std::ldexp(ut[c], e2));
      angular_velocities[3 * i + c] = inv_eta * (std::ldexp(wf[c], e2) + std::ldexp(rr[c], e3));
    }
  }
}

}  // namespace rpyfmm::rpy
