// rpyfmm — DirectRpy: U_i = sum_j M_ij F_j over all pairs (docs/theory/rpy.md).
//
// Per target particle i and block of sources j, the pair scalars (f, g/r^2)
// are evaluated in branch-free form (every regime computed, then selected)
// into small buffers, then applied to every right-hand side. Two versions of
// the scalar loops: portable C++ that GCC vectorizes (sqrt and division per
// pair) and AVX-512F intrinsics (1/r by rsqrt14 + Newton, no division),
// chosen at run time (fmm/direct_simd.hpp). The branching forms of
// rpy_kernel.hpp are the reference the tests compare against.
#include "rpyfmm/rpy/direct_operator.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <span>
#include <string>
#include <vector>

#include "direct_block_sums.hpp"
#include "length_units.hpp"
#include "load_scaling.hpp"
#include "pair_block_sum.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/fmm/direct_simd.hpp"

namespace rpyfmm::rpy {
namespace {

constexpr std::size_t kBlock = detail::kDirectBlock;
constexpr double kInv6Pi = 1.0 / (6.0 * std::numbers::pi);
constexpr double kInv8Pi = 1.0 / (8.0 * std::numbers::pi);

// Scalars of one target i against sources [j0, j0 + nb): dx = x_i - x_j etc.,
// f and gr = g / r^2 so that M_ij = (f I + gr d d^T) / eta.
// Equal radii a: Guan eq. 3.1; Fiore et al. 2017 eq. 4 (docs/theory/rpy.md).
void scalars_equal(double xi, double yi, double zi, const double* __restrict x, const double* __restrict y,
                   const double* __restrict z, std::size_t nb, double a, double* __restrict dx, double* __restrict dy,
                   double* __restrict dz, double* __restrict f, double* __restrict gr) {
  simd_dispatch([=]() RPYFMM_SIMD_BODY {
    const double c6 = kInv6Pi / a;
    const double two_a = 2.0 * a;
    const double a2 = a * a;
    const double near_f = 9.0 / (32.0 * a);
    const double near_g = c6 * 3.0 / (32.0 * a);
#pragma omp simd
    for (std::size_t j = 0; j < nb; ++j) {
      const double ddx = xi - x[j], ddy = yi - y[j], ddz = zi - z[j];
      const double r2 = ddx * ddx + ddy * ddy + ddz * ddz;
      const double r = std::sqrt(r2);
      const double inv_r = r2 > 0.0 ? 1.0 / r : 0.0;
      const double inv_r2 = inv_r * inv_r;
      const double s = a2 * inv_r2;
      const double c8 = kInv8Pi * inv_r;
      const bool far = r > two_a;
      // far: f = (1 + 2a^2/(3r^2))/(8 pi r), g = (1 - 2a^2/r^2)/(8 pi r)
      // near (r <= 2a): f = (1 - 9r/(32a))/(6 pi a), g = (3r/(32a))/(6 pi a), g/r^2 = 3/(32 a r)/(6 pi a)
      f[j] = far ? c8 * (1.0 + (2.0 / 3.0) * s) : c6 * (1.0 - near_f * r);
      gr[j] = far ? c8 * (1.0 - 2.0 * s) * inv_r2 : near_g * inv_r;
      dx[j] = ddx;
      dy[j] = ddy;
      dz[j] = ddz;
    }
  });
}

// Different radii (Zuk et al. 2014; docs/theory/rpy.md), the three regimes selected per pair.
void scalars_general(double xi, double yi, double zi, double ai, const double* __restrict x, const double* __restrict y,
                     const double* __restrict z, const double* __restrict a, const double* __restrict inv_a,
                     std::size_t nb, double* __restrict dx, double* __restrict dy, double* __restrict dz,
                     double* __restrict f, double* __restrict gr) {
  simd_dispatch([=]() RPYFMM_SIMD_BODY {
    const double inv_ai = 1.0 / ai;
#pragma omp simd
    for (std::size_t j = 0; j < nb; ++j) {
      const double aj = a[j];
      const double ddx = xi - x[j], ddy = yi - y[j], ddz = zi - z[j];
      const double r2 = ddx * ddx + ddy * ddy + ddz * ddz;
      const double r = std::sqrt(r2);
      const double inv_r = r2 > 0.0 ? 1.0 / r : 0.0;
      const double inv_r2 = inv_r * inv_r;
      const double sum = ai + aj;
      const double diff = ai - aj;
      const double adiff = std::fabs(diff);
      // far, r > ai + aj
      const double s = (ai * ai + aj * aj) * inv_r2;
      const double c8 = kInv8Pi * inv_r;
      const double f_far = c8 * (1.0 + s / 3.0);
      const double gr_far = c8 * (1.0 - s) * inv_r2;
      // partial overlap, |ai - aj| < r <= ai + aj (divided through by r^2, see rpy_kernel.hpp)
      const double c = kInv6Pi * inv_ai * inv_a[j];
      const double d2r = diff * diff * inv_r;
      const double pr = d2r + 3.0 * r;
      const double qr = d2r - r;
      const double inv_32r = inv_r * (1.0 / 32.0);
      const double f_mid = c * (0.5 * sum - pr * pr * inv_32r);
      const double gr_mid = c * 3.0 * qr * qr * inv_32r * inv_r2;
      // one inside the other (and r = 0), r <= |ai - aj|
      const double f_in = kInv6Pi * std::min(inv_ai, inv_a[j]);  // 1/(6 pi max(ai, aj))
      const bool far = r > sum;
      const bool inside = r <= adiff;
      f[j] = far ? f_far : (inside ? f_in : f_mid);
      gr[j] = far ? gr_far : (inside ? 0.0 : gr_mid);
      dx[j] = ddx;
      dy[j] = ddy;
      dz[j] = ddz;
    }
  });
}

#if defined(RPYFMM_HAVE_DIRECT_AVX512)
// GCC 12's _mm512_abs_pd uses an undefined vector: silence its false -Wmaybe-uninitialized.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wuninitialized"
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
// The same two loops with AVX-512F, 1/r by rsqrt14 + Newton (direct_simd.hpp)
// and r = r^2 / r; regimes chosen by lane masks.
using fmm::detail::rsqrt_or_zero;

// r = r^2 * (1/r), keeping r = r^2 where r^2 is 0 or overflowed to inf (inf * 0 would be NaN).
RPYFMM_DIRECT_AVX512 inline __m512d finite_r(__m512d r2, __m512d ir) {
  const __mmask8 fin = _mm512_cmp_pd_mask(r2, _mm512_set1_pd(__builtin_inf()), _CMP_LT_OQ);
  return _mm512_mask_mul_pd(r2, fin, r2, ir);
}

RPYFMM_DIRECT_AVX512 void scalars_equal_avx512(double xi, double yi, double zi, const double* x, const double* y,
                                               const double* z, std::size_t nb, double a, double* dx, double* dy,
                                               double* dz, double* f, double* gr) {
  const __m512d vx = _mm512_set1_pd(xi), vy = _mm512_set1_pd(yi), vz = _mm512_set1_pd(zi);
  const __m512d c6 = _mm512_set1_pd(kInv6Pi / a), c8 = _mm512_set1_pd(kInv8Pi), two_a = _mm512_set1_pd(2.0 * a);
  const __m512d a2 = _mm512_set1_pd(a * a), one = _mm512_set1_pd(1.0);
  const __m512d near_f = _mm512_set1_pd(9.0 / (32.0 * a)), near_g = _mm512_set1_pd(kInv6Pi / a * 3.0 / (32.0 * a));
  for (std::size_t j = 0; j < nb; j += 8) {
    const __mmask8 m = nb - j >= 8 ? __mmask8(0xff) : __mmask8((1u << (nb - j)) - 1u);
    const __m512d ddx = _mm512_sub_pd(vx, _mm512_maskz_loadu_pd(m, x + j));
    const __m512d ddy = _mm512_sub_pd(vy, _mm512_maskz_loadu_pd(m, y + j));
    const __m512d ddz = _mm512_sub_pd(vz, _mm512_maskz_loadu_pd(m, z + j));
    const __m512d r2 = _mm512_fmadd_pd(ddz, ddz, _mm512_fmadd_pd(ddy, ddy, _mm512_mul_pd(ddx, ddx)));
    const __m512d ir = rsqrt_or_zero(r2);
    const __m512d r = finite_r(r2, ir);
    const __m512d ir2 = _mm512_mul_pd(ir, ir);
    const __m512d sa = _mm512_mul_pd(a2, ir2);
    const __m512d c8r = _mm512_mul_pd(c8, ir);
    const __mmask8 far = _mm512_cmp_pd_mask(r, two_a, _CMP_GT_OQ);
    const __m512d f_far = _mm512_mul_pd(c8r, _mm512_fmadd_pd(_mm512_set1_pd(2.0 / 3.0), sa, one));
    const __m512d g_far = _mm512_mul_pd(_mm512_mul_pd(c8r, _mm512_fnmadd_pd(_mm512_set1_pd(2.0), sa, one)), ir2);
    const __m512d f_near = _mm512_mul_pd(c6, _mm512_fnmadd_pd(near_f, r, one));
    const __m512d g_near = _mm512_mul_pd(near_g, ir);
    _mm512_mask_storeu_pd(f + j, m, _mm512_mask_blend_pd(far, f_near, f_far));
    _mm512_mask_storeu_pd(gr + j, m, _mm512_mask_blend_pd(far, g_near, g_far));
    _mm512_mask_storeu_pd(dx + j, m, ddx);
    _mm512_mask_storeu_pd(dy + j, m, ddy);
    _mm512_mask_storeu_pd(dz + j, m, ddz);
  }
}

RPYFMM_DIRECT_AVX512 void scalars_general_avx512(double xi, double yi, double zi, double ai, const double* x,
                                                 const double* y, const double* z, const double* a, const double* inv_a,
                                                 std::size_t nb, double* dx, double* dy, double* dz, double* f,
                                                 double* gr) {
  const __m512d vx = _mm512_set1_pd(xi), vy = _mm512_set1_pd(yi), vz = _mm512_set1_pd(zi);
  const __m512d vai = _mm512_set1_pd(ai), vinv_ai = _mm512_set1_pd(1.0 / ai), one = _mm512_set1_pd(1.0);
  const __m512d c6 = _mm512_set1_pd(kInv6Pi), c8 = _mm512_set1_pd(kInv8Pi), zero = _mm512_setzero_pd();
  for (std::size_t j = 0; j < nb; j += 8) {
    const __mmask8 m = nb - j >= 8 ? __mmask8(0xff) : __mmask8((1u << (nb - j)) - 1u);
    const __m512d aj = _mm512_mask_loadu_pd(vai, m, a + j);  // idle lanes: aj = ai (finite)
    const __m512d inv_aj = _mm512_mask_loadu_pd(vinv_ai, m, inv_a + j);
    const __m512d ddx = _mm512_sub_pd(vx, _mm512_maskz_loadu_pd(m, x + j));
    const __m512d ddy = _mm512_sub_pd(vy, _mm512_maskz_loadu_pd(m, y + j));
    const __m512d ddz = _mm512_sub_pd(vz, _mm512_maskz_loadu_pd(m, z + j));
    const __m512d r2 = _mm512_fmadd_pd(ddz, ddz, _mm512_fmadd_pd(ddy, ddy, _mm512_mul_pd(ddx, ddx)));
    const __m512d ir = rsqrt_or_zero(r2);
    const __m512d r = finite_r(r2, ir);
    const __m512d ir2 = _mm512_mul_pd(ir, ir);
    const __m512d sum = _mm512_add_pd(vai, aj);
    const __m512d diff = _mm512_sub_pd(vai, aj);
    // far, r > ai + aj
    const __m512d s = _mm512_mul_pd(_mm512_fmadd_pd(aj, aj, _mm512_mul_pd(vai, vai)), ir2);
    const __m512d c8r = _mm512_mul_pd(c8, ir);
    const __m512d f_far = _mm512_mul_pd(c8r, _mm512_fmadd_pd(s, _mm512_set1_pd(1.0 / 3.0), one));
    const __m512d g_far = _mm512_mul_pd(_mm512_mul_pd(c8r, _mm512_sub_pd(one, s)), ir2);
    // partial overlap (divided through by r^2, see rpy_kernel.hpp)
    const __m512d c = _mm512_mul_pd(c6, _mm512_mul_pd(vinv_ai, inv_aj));
    const __m512d d2r = _mm512_mul_pd(_mm512_mul_pd(diff, diff), ir);
    const __m512d pr = _mm512_fmadd_pd(_mm512_set1_pd(3.0), r, d2r);
    const __m512d qr = _mm512_sub_pd(d2r, r);
    const __m512d inv_32r = _mm512_mul_pd(ir, _mm512_set1_pd(1.0 / 32.0));
    const __m512d f_mid =
        _mm512_mul_pd(c, _mm512_fnmadd_pd(_mm512_mul_pd(pr, pr), inv_32r, _mm512_mul_pd(_mm512_set1_pd(0.5), sum)));
    const __m512d g_mid = _mm512_mul_pd(_mm512_mul_pd(c, _mm512_set1_pd(3.0)),
                                        _mm512_mul_pd(_mm512_mul_pd(qr, qr), _mm512_mul_pd(inv_32r, ir2)));
    // one inside the other (and r = 0)
    const __m512d f_in = _mm512_mul_pd(c6, _mm512_min_pd(vinv_ai, inv_aj));
    const __mmask8 far = _mm512_cmp_pd_mask(r, sum, _CMP_GT_OQ);
    const __mmask8 inside = _mm512_cmp_pd_mask(r, _mm512_abs_pd(diff), _CMP_LE_OQ);
    const __m512d fv = _mm512_mask_blend_pd(far, _mm512_mask_blend_pd(inside, f_mid, f_in), f_far);
    const __m512d gv = _mm512_mask_blend_pd(far, _mm512_mask_blend_pd(inside, g_mid, zero), g_far);
    _mm512_mask_storeu_pd(f + j, m, fv);
    _mm512_mask_storeu_pd(gr + j, m, gv);
    _mm512_mask_storeu_pd(dx + j, m, ddx);
    _mm512_mask_storeu_pd(dy + j, m, ddy);
    _mm512_mask_storeu_pd(dz + j, m, ddz);
  }
}
#pragma GCC diagnostic pop
#endif  // RPYFMM_HAVE_DIRECT_AVX512

// u += sum_j (f_j F_j + gr_j d_j (d_j . F_j)) over one block, forces in SoA (pair_block_sum.hpp).
void accumulate(std::size_t nb, const double* __restrict dx, const double* __restrict dy, const double* __restrict dz,
                const double* __restrict f, const double* __restrict gr, const double* __restrict fx,
                const double* __restrict fy, const double* __restrict fz, double& ux, double& uy, double& uz) {
  simd_dispatch([=, &ux, &uy, &uz]() RPYFMM_SIMD_BODY {
    double sx, sy, sz;
    detail::sum_pair_blocks(nb, dx, dy, dz, f, gr, fx, fy, fz, sx, sy, sz);
    ux += sx;
    uy += sy;
    uz += sz;
  });
}

// Per-block scratch of one thread: separations and pair scalars of up to kBlock sources.
struct PairScratch {
  PairScratch() = default;
  PairScratch(const PairScratch&) = delete;
  PairScratch& operator=(const PairScratch&) = delete;
  std::vector<double> buf = std::vector<double>(5 * kBlock);
  double* dx = buf.data();
  double* dy = dx + kBlock;
  double* dz = dy + kBlock;
  double* f = dz + kBlock;
  double* gr = f + kBlock;
};

// The pair scalars of target i of `t` against sources [j0, j0 + nb) of `s`, by the kernel of this
// CPU's level; with equal radii every radius is t.a[i].
void block_scalars(const detail::DirectParticles& t, std::size_t i, const detail::DirectParticles& s, std::size_t j0,
                   std::size_t nb, bool equal, PairScratch& b) {
#if defined(RPYFMM_HAVE_DIRECT_AVX512)
  if (simd_level() == SimdLevel::avx512) {
    if (equal) {
      scalars_equal_avx512(t.x[i], t.y[i], t.z[i], s.x + j0, s.y + j0, s.z + j0, nb, t.a[i], b.dx, b.dy, b.dz, b.f,
                           b.gr);
    } else {
      scalars_general_avx512(t.x[i], t.y[i], t.z[i], t.a[i], s.x + j0, s.y + j0, s.z + j0, s.a + j0, s.inv_a + j0, nb,
                             b.dx, b.dy, b.dz, b.f, b.gr);
    }
    return;
  }
#endif
  if (equal) {
    scalars_equal(t.x[i], t.y[i], t.z[i], s.x + j0, s.y + j0, s.z + j0, nb, t.a[i], b.dx, b.dy, b.dz, b.f, b.gr);
  } else {
    scalars_general(t.x[i], t.y[i], t.z[i], t.a[i], s.x + j0, s.y + j0, s.z + j0, s.a + j0, s.inv_a + j0, nb, b.dx,
                    b.dy, b.dz, b.f, b.gr);
  }
}

}  // namespace

void detail::store_direct_particles(std::span<const double> positions, std::span<const double> radii,
                                    const LengthUnits& units, const DirectParticleArrays& out) {
  std::vector<double> scaled_x, scaled_a;
  if (units.exponent != 0) {
    to_units(units, positions, radii, scaled_x, scaled_a);
    positions = scaled_x;
    radii = scaled_a;
  }
  const std::size_t n = radii.size();
  out.x.resize(n);
  out.y.resize(n);
  out.z.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    out.x[i] = positions[3 * i];
    out.y[i] = positions[3 * i + 1];
    out.z[i] = positions[3 * i + 2];
  }
  out.a.assign(radii.begin(), radii.end());
  out.inv_a.resize(n);
  for (std::size_t i = 0; i < n; ++i) out.inv_a[i] = 1.0 / out.a[i];
}

void detail::add_direct_block_sums(const DirectParticles& targets, std::size_t n_targets,
                                   const DirectParticles& sources, std::span<const DirectForces> forces,
                                   std::size_t n_sources, bool equal_radii, double* acc) {
  const auto n = static_cast<long long>(n_targets);
  const std::size_t nrhs = forces.size();
#pragma omp parallel
  {
    PairScratch b;
#pragma omp for schedule(dynamic, 16)
    for (long long ii = 0; ii < n; ++ii) {
      const auto i = static_cast<std::size_t>(ii);
      for (std::size_t j0 = 0; j0 < n_sources; j0 += kBlock) {
        const std::size_t nb = std::min(kBlock, n_sources - j0);
        block_scalars(targets, i, sources, j0, nb, equal_radii, b);
        for (std::size_t k = 0; k < nrhs; ++k) {
          double* u = acc + 3 * (nrhs * i + k);
          accumulate(nb, b.dx, b.dy, b.dz, b.f, b.gr, forces[k].x + j0, forces[k].y + j0, forces[k].z + j0, u[0], u[1],
                     u[2]);
        }
      }
    }
  }
}

DirectRpy::DirectRpy(Geometry geometry, double viscosity) : MobilityOperator(geometry, viscosity, "DirectRpy") {
  require(geometry.is_open(), ErrorCode::not_supported, "DirectRpy",
          "periodic geometry is not supported by the direct operator (use the PSE operator)");
}

void DirectRpy::on_positions_set() {
  const detail::LengthUnits units =
      detail::choose_length_units(detail::bounding_box(positions()), radii(), "DirectRpy::set_positions");
  scale_exponent_ = units.exponent;
  detail::store_direct_particles(positions(), radii(), units, {x_, y_, z_, a_, inv_a_});
}

void DirectRpy::do_apply(const double* forces, double* velocities, std::size_t nrhs) const {
  sum_rows(forces, nrhs, 0, size(), velocities);
}

void DirectRpy::apply_rows(std::size_t first, std::size_t count, std::span<const double> forces,
                           std::span<double> velocities) const {
  require_positions("apply_rows");
  const char* where = "DirectRpy::apply_rows";
  require(first <= size() && count <= size() - first, ErrorCode::invalid_argument, where,
          "rows [" + std::to_string(first) + ", " + std::to_string(first + count) + ") are not within the " +
              std::to_string(size()) + " particles");
  require_size(forces, 3 * size(), where, "forces");
  require_size(std::span<const double>(velocities.data(), velocities.size()), 3 * count, where, "velocities");
  require_finite(forces, where, "forces", 3);
  if (count == 0) return;
  // MobilityOperator::apply_block's load scaling, from all forces, so that the rows are apply()'s.
  const int k = detail::load_scale_exponent({forces});
  if (k == 0) {
    sum_rows(forces.data(), 1, first, count, velocities.data());
  } else {
    std::vector<double> scaled(forces.begin(), forces.end());
    for (double& f : scaled) f = std::ldexp(f, -k);
    sum_rows(scaled.data(), 1, first, count, velocities.data());
    for (double& u : velocities) u = std::ldexp(u, k);
  }
  detail::require_finite_result(velocities, where, "velocities", "forces");
}

void DirectRpy::sum_rows(const double* forces, std::size_t nrhs, std::size_t first, std::size_t count,
                         double* velocities) const {
  const std::size_t n = size();
  const double inv_eta = 1.0 / viscosity();
  // Forces to structure-of-arrays, one (fx, fy, fz) triple of length n per right-hand side.
  std::vector<double> fsoa(3 * n * nrhs);
  std::vector<detail::DirectForces> columns(nrhs);
  for (std::size_t k = 0; k < nrhs; ++k) {
    const double* fk = forces + 3 * n * k;
    double* s = fsoa.data() + 3 * n * k;
    for (std::size_t j = 0; j < n; ++j) {
      s[j] = fk[3 * j];
      s[n + j] = fk[3 * j + 1];
      s[2 * n + j] = fk[3 * j + 2];
    }
    columns[k] = {s, s + n, s + 2 * n};
  }
  std::vector<double> acc(3 * nrhs * count, 0.0);
  const detail::DirectParticles targets{x_.data() + first, y_.data() + first, z_.data() + first, a_.data() + first,
                                        inv_a_.data() + first};
  detail::add_direct_block_sums(targets, count, {x_.data(), y_.data(), z_.data(), a_.data(), inv_a_.data()}, columns, n,
                                equal_radii(), acc.data());
  for (std::size_t i = 0; i < count; ++i)
    for (std::size_t k = 0; k < nrhs; ++k) {
      double* u = velocities + 3 * count * k + 3 * i;
      const double* sums = acc.data() + 3 * (nrhs * i + k);
      // Back from the units of length_units.hpp: M(x, a) = 2^-e M(2^-e x, 2^-e a) (exact).
      for (int c = 0; c < 3; ++c) u[c] = std::ldexp(inv_eta * sums[c], -scale_exponent_);
    }
}

}  // namespace rpyfmm::rpy
