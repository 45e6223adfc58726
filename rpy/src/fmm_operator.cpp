// rpyfmm — FmmRpy: RPY mobility from Laplace FMM calls (MATH.md §2) + exact near field.
#include "rpyfmm/rpy/fmm_operator.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <string>

#include "fmm_near_kernels.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/fmm/direct_simd.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"
#include "rpyfmm/rpy/rpy_kernel.hpp"

namespace rpyfmm::rpy {
namespace {

constexpr double pi = std::numbers::pi;
// Column of the FMM result row [pot, gx, gy, gz, hxx, hyy, hzz, hxy, hxz, hyz] holding H(k, m).
constexpr std::array<std::array<int, 3>, 3> kHessianColumn = {{{4, 7, 8}, {7, 5, 9}, {8, 9, 6}}};

// Laplace FMM tolerance for a requested RPY tolerance. The far field combines
// up to 7 outputs with partial cancellation (x_m E_k(F^m) - E_k(x.F)); measured
// on the test configurations, errors stay below the FMM's own eps, which is
// itself conservative (tests/rpy/test_fmm_operator.cpp holds the contract).
double laplace_eps_for(double tolerance) {
  return tolerance;
}

// Leaf capacity when the user leaves it at 0 (bench/rpy/RESULTS.md "Leaf capacity", 1 thread).
// Four densities per product make the far field dearer relative to the near field than in one
// Laplace evaluation, so from 6 digits on the best leaves are larger than the Laplace default
// wherever the P2P runs without AVX-512: 400 / 600 / 800 points at 6 / 9 / 12 digits on both
// machines measured. At 3 digits the near-field kernel's speed decides: 200 points with the AVX-512
// kernels (random suspension N = 3e3 ... 2e5, Intel machine), 150 with AVX2 (AMD Zen-1 machine:
// suspension N = 1e3 ... 1e5 within 1.26x of the best of 100/150/200/400, 2x faster than 200 at
// N = 1e5; 100 is best from 1e4 up but 1.7x slower at N = 1e3).
int default_leaf_capacity(double eps) {
  switch (fmm::fmm_table_digits_for(eps)) {
    case 3: return fmm::detail::avx512_kernels_active() ? 200 : 150;
    case 6: return 400;
    case 9: return 600;
    default: return 800;
  }
}

}  // namespace

FmmRpy::FmmRpy(Geometry geometry, double viscosity, FmmRpyOptions options)
    : MobilityOperator(geometry, viscosity, "FmmRpy"), options_(options) {
  require(geometry.is_open(), ErrorCode::not_supported, "FmmRpy",
          "periodic geometry is not supported by the free-space FMM operator (use the PSE operator)");
  require_in_range(options_.tolerance, 1e-12, 1e-1, "FmmRpy", "tolerance");
  require(options_.leaf_capacity >= 0, ErrorCode::invalid_argument, "FmmRpy",
          "leaf_capacity must be >= 0 (0 = automatic), got " + std::to_string(options_.leaf_capacity));
  laplace_eps_ = laplace_eps_for(options_.tolerance);
}

FmmRpy::~FmmRpy() = default;

StageTimes FmmRpy::last_timings() const {
  return timings_;
}

void FmmRpy::on_positions_set() {
  const std::size_t n = size();
  const auto x = positions();
  // Centre the coordinates: the far field subtracts x_i,m E_k(F^m) and E_k(x.F), whose
  // FMM errors scale with |x|; centring keeps them at the scale of the cloud (translation invariance).
  std::array<double, 3> lo{x[0], x[1], x[2]}, hi = lo;
  for (std::size_t i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) {
      lo[c] = std::min(lo[c], x[3 * i + c]);
      hi[c] = std::max(hi[c], x[3 * i + c]);
    }
  centered_.resize(3 * n);
  for (std::size_t i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) centered_[3 * i + c] = x[3 * i + c] - 0.5 * (lo[c] + hi[c]);

  const double a_max = *std::max_element(radii().begin(), radii().end());
  fmm::FmmOptions fo;
  fo.eps = laplace_eps_;
  fo.leaf_capacity = options_.leaf_capacity > 0 ? options_.leaf_capacity : default_leaf_capacity(laplace_eps_);
  fo.near_field = false;
  fo.export_direct_far = true;     // W/X pairs summed directly: one RPY pair block beats 4-7 Laplace densities
  fo.min_leaf_side = 2.0 * a_max;  // overlapping pairs (r <= a_i + a_j) are always U-list pairs
  fmm_ = std::make_unique<fmm::LaplaceFmm>(fo);
  fmm_->set_points(centered_);

  // Group the U-list pairs by target leaf so that the near field is race-free in parallel.
  const fmm::NearField& near = fmm_->near_field();
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs = near.pairs;
  std::sort(pairs.begin(), pairs.end());
  near_targets_.clear();
  near_begin_.clear();
  near_sources_.clear();
  for (std::size_t p = 0; p < pairs.size(); ++p) {
    if (p == 0 || pairs[p].first != pairs[p - 1].first) {
      near_targets_.push_back(pairs[p].first);
      near_begin_.push_back(near_sources_.size());
    }
    near_sources_.push_back(pairs[p].second);
  }
  near_begin_.push_back(near_sources_.size());
}

void FmmRpy::do_apply(const double* forces, double* velocities, std::size_t nrhs) const {
  StopWatch total;
  const std::size_t n = size();
  const bool equal = equal_radii();
  const std::size_t per_rhs = equal ? 4 : 7;
  const std::size_t nd = per_rhs * nrhs;
  const auto a = radii();
  const double eta = viscosity();

  // Charge vectors (MATH.md §2): F^(m), x.F, and for different radii a^2 F^(m).
  StopWatch watch;
  std::vector<double> charges(nd * n);
  std::vector<unsigned> outputs(nd);
  for (std::size_t k = 0; k < nrhs; ++k) {
    const double* f = forces + 3 * n * k;
    double* q = charges.data() + per_rhs * n * k;
    for (std::size_t m = 0; m < 3; ++m) {
      outputs[per_rhs * k + m] = fmm::potential | fmm::gradient | fmm::hessian;
      for (std::size_t j = 0; j < n; ++j) q[m * n + j] = f[3 * j + m];
    }
    outputs[per_rhs * k + 3] = fmm::gradient;
    for (std::size_t j = 0; j < n; ++j) {
      const double* xj = &centered_[3 * j];
      q[3 * n + j] = xj[0] * f[3 * j] + xj[1] * f[3 * j + 1] + xj[2] * f[3 * j + 2];
    }
    if (!equal) {
      for (std::size_t m = 0; m < 3; ++m) {
        outputs[per_rhs * k + 4 + m] = fmm::hessian;
        for (std::size_t j = 0; j < n; ++j) q[(4 + m) * n + j] = a[j] * a[j] * f[3 * j + m];
      }
    }
  }
  timings_.clear();
  timings_["rpy_charges"] = watch.seconds();

  std::vector<double> results(nd * n * 10);
  fmm_->evaluate(charges, nd, outputs, results);
  for (const auto& [stage, seconds] : fmm_->last_timings()) timings_[stage] = seconds;

  // Combine (MATH.md §2); E = -g, T = -H.
  watch.restart();
  const double c1 = 1.0 / (8.0 * pi * eta);
  const double c2 = 1.0 / (24.0 * pi * eta);
  const auto nn = static_cast<std::int64_t>(n);
  for (std::size_t k = 0; k < nrhs; ++k) {
    const double* r = results.data() + per_rhs * n * 10 * k;
    double* u = velocities + 3 * n * k;
#pragma omp parallel for schedule(static)
    for (std::int64_t ii = 0; ii < nn; ++ii) {
      const auto i = static_cast<std::size_t>(ii);
      const double* xi = &centered_[3 * i];
      const double ai2 = a[i] * a[i];
      const double* rxF = r + (3 * n + i) * 10;  // results of x.F at target i
      for (int c = 0; c < 3; ++c) {
        double oseen = r[(c * n + i) * 10];  // phi(F^(c))
        double dipole = 0.0;
        for (int m = 0; m < 3; ++m) {
          const double* rm = r + (m * n + i) * 10;
          oseen -= xi[m] * rm[1 + c];          // + x_m E_c(F^m),  E = -g
          dipole -= rm[kHessianColumn[c][m]];  // T_cm(F^m),       T = -H
        }
        oseen += rxF[1 + c];  // - E_c(x.F)
        double value = c1 * oseen + c2 * ai2 * dipole;
        if (equal) {
          value += c2 * ai2 * dipole;  // a_j^2 = a_i^2
        } else {
          double dipole_a2 = 0.0;
          for (int m = 0; m < 3; ++m) dipole_a2 -= r[((4 + m) * n + i) * 10 + kHessianColumn[c][m]];
          value += c2 * dipole_a2;
        }
        u[3 * i + c] = value;
      }
    }
  }
  timings_["rpy_far"] = watch.seconds();

  watch.restart();
  apply_near_field(forces, velocities, nrhs);
  timings_["rpy_near"] = watch.seconds();
  timings_["rpy_total"] = total.seconds();
}

void FmmRpy::apply_near_field(const double* forces, double* velocities, std::size_t nrhs) const {
  const fmm::NearField& near = fmm_->near_field();
  const std::size_t n = size();
  const auto x = positions();
  const auto a = radii();
  const double inv_eta = 1.0 / viscosity();
  const bool equal = equal_radii();
  const auto ntl = static_cast<std::int64_t>(near_targets_.size());
  // Each target leaf is owned by one thread: its velocities are written by nobody else, and the
  // order of summation is fixed, so results do not depend on the thread count.
#pragma omp parallel
  {
    // Sources of all U-list leaves of one target leaf, gathered into structure-of-arrays
    // buffers so that the pair loop below vectorizes.
    std::vector<double> sx, sy, sz, sa, sf, pair_buf;
    std::vector<std::size_t> sid;
#pragma omp for schedule(dynamic, 4)
    for (std::int64_t t = 0; t < ntl; ++t) {
      sx.clear();
      sy.clear();
      sz.clear();
      sa.clear();
      sid.clear();
      for (std::size_t s = near_begin_[t]; s < near_begin_[t + 1]; ++s) {
        for (std::size_t j : near.sources(near_sources_[s])) {
          sx.push_back(x[3 * j]);
          sy.push_back(x[3 * j + 1]);
          sz.push_back(x[3 * j + 2]);
          sa.push_back(a[j]);
          sid.push_back(j);
        }
      }
      const std::size_t m = sid.size();
      sf.resize(3 * m * nrhs);
      if (nrhs > 1) {
        // Block product: every rhs's forces in SoA, then per target the pair scalars once
        // and one accumulation per rhs (the geometry is most of the near-field work).
        for (std::size_t k = 0; k < nrhs; ++k) {
          const double* f = forces + 3 * n * k;
          double* sk = sf.data() + 3 * m * k;
          for (std::size_t q = 0; q < m; ++q)
            for (int c = 0; c < 3; ++c) sk[c * m + q] = f[3 * sid[q] + c];
        }
        pair_buf.resize(5 * m);
        double* dxb = pair_buf.data();
        double* dyb = dxb + m;
        double* dzb = dyb + m;
        double* fsb = dzb + m;
        double* grb = fsb + m;
        for (std::size_t i : near.targets(near_targets_[t])) {
          const double ai = a[i];
          detail::near_pair_scalars(m, sx.data(), sy.data(), sz.data(), equal ? nullptr : sa.data(), sid.data(),
                                    x[3 * i], x[3 * i + 1], x[3 * i + 2], ai, i, dxb, dyb, dzb, fsb, grb);
          const double self = rpy_self(ai);  // M_ii = I / (6 pi eta a_i)
          for (std::size_t k = 0; k < nrhs; ++k) {
            const double* f = forces + 3 * n * k;
            const double* sk = sf.data() + 3 * m * k;
            double u[3];
            detail::near_accumulate(m, dxb, dyb, dzb, fsb, grb, sk, sk + m, sk + 2 * m, u);
            double* ui = velocities + 3 * n * k + 3 * i;
            ui[0] += inv_eta * (u[0] + self * f[3 * i]);
            ui[1] += inv_eta * (u[1] + self * f[3 * i + 1]);
            ui[2] += inv_eta * (u[2] + self * f[3 * i + 2]);
          }
        }
        continue;
      }
      for (std::size_t k = 0; k < nrhs; ++k) {
        const double* f = forces + 3 * n * k;
        for (std::size_t q = 0; q < m; ++q)
          for (int c = 0; c < 3; ++c) sf[c * m + q] = f[3 * sid[q] + c];
        const double* fx = sf.data();
        const double* fy = fx + m;
        const double* fz = fy + m;
        for (std::size_t i : near.targets(near_targets_[t])) {
          const double xi = x[3 * i], yi = x[3 * i + 1], zi = x[3 * i + 2], ai = a[i];
          double u[3];
          if (equal) {
            detail::near_pair_sum_equal(m, sx.data(), sy.data(), sz.data(), sid.data(), fx, fy, fz, xi, yi, zi, ai, i,
                                        u);
          } else {
            detail::near_pair_sum(m, sx.data(), sy.data(), sz.data(), sa.data(), sid.data(), fx, fy, fz, xi, yi, zi, ai,
                                  i, u);
          }
          const double ux = u[0], uy = u[1], uz = u[2];
          const double self = rpy_self(ai);  // M_ii = I / (6 pi eta a_i)
          double* ui = velocities + 3 * n * k + 3 * i;
          ui[0] += inv_eta * (ux + self * f[3 * i]);
          ui[1] += inv_eta * (uy + self * f[3 * i + 1]);
          ui[2] += inv_eta * (uz + self * f[3 * i + 2]);
        }
      }
    }
  }
}

}  // namespace rpyfmm::rpy
