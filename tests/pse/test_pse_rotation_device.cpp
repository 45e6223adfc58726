// The host-device functions of the CUDA rotation path (rpy/src/pse/rotation_pair_device.hpp,
// rpy/src/pse/rotation_modes.hpp), run on the host against the CPU operator's code: the device
// rows' per-pair sums over every pair within r_cut give the CPU rows' rotational real-space
// product, and the per-mode scaling by linear index with its own noise draw gives the CPU's
// line-by-line pass bit for bit.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "../../rpy/src/pse/kernels_common.hpp"
#include "../../rpy/src/pse/real_space_sum.hpp"
#include "../../rpy/src/pse/rotation_modes.hpp"
#include "../../rpy/src/pse/rotation_pair_device.hpp"
#include "../../rpy/src/pse/rotation_real_space_sum.hpp"
#include "../../rpy/src/pse/wave_space.hpp"
#include "ewald_reference.hpp"
#include "rpyfmm/rpy/pse/pse_parameters.hpp"
#include "rpyfmm/rpy/random.hpp"

using namespace rpyfmm::rpy;
using namespace rpyfmm::rpy::pse;

namespace {

constexpr double kViscosity = 1.3;

/// [u; w] += the rotational real-space rows as the CUDA cell-list kernel sums them: every pair
/// j != i with |d|^2 < r_cut^2 (minimum image) by rotation_pair_terms, plus h(0) T_i, over eta.
void device_rows_on_host(const PseRotationTable& tab, const PseParameters& p, const std::array<double, 3>& L,
                         const std::vector<double>& x, const std::vector<double>& f, const std::vector<double>& t,
                         std::vector<double>& u, std::vector<double>& w) {
  const detail::RotationTableView view{tab.data(), tab.inv_dr(), tab.unit_c(), tab.unit_hk()};
  const std::size_t n = x.size() / 3;
  for (std::size_t i = 0; i < n; ++i) {
    double acc[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    for (std::size_t j = 0; j < n; ++j) {
      if (j == i) continue;
      double d[3];
      for (int c = 0; c < 3; ++c) d[c] = detail::minimum_image(x[3 * i + c] - x[3 * j + c], L[c], 1.0 / L[c]);
      if (!(d[0] * d[0] + d[1] * d[1] + d[2] * d[2] < p.r_cut * p.r_cut)) continue;
      const detail::RotationPairTerms q = detail::rotation_pair_terms(
          d[0], d[1], d[2], f[3 * j], f[3 * j + 1], f[3 * j + 2], t[3 * j], t[3 * j + 1], t[3 * j + 2], view);
      const double terms[6] = {q.ux, q.uy, q.uz, q.wx, q.wy, q.wz};
      for (int c = 0; c < 6; ++c) acc[c] += terms[c];
    }
    for (int c = 0; c < 3; ++c) {
      u[3 * i + c] += acc[c] / kViscosity;
      w[3 * i + c] += (tab.self() * t[3 * i + c] + acc[3 + c]) / kViscosity;
    }
  }
}

}  // namespace

TEST(PseRotationDeviceFunctions, PairSumsOverAllPairsGiveTheCpuRows) {
  const std::array<double, 3> L = {14.0, 12.0, 15.0};
  auto x = pse_test::random_points(300, L, 61);
  for (int d = 0; d < 3; ++d) {
    x[3 * 5 + d] = x[3 * 2 + d];                  // coincident
    x[3 * 8 + d] = x[3 * 6 + d] + 0.3 * (d + 1);  // overlapping
  }
  auto f = pse_test::random_points(300, {2.0, 2.0, 2.0}, 62), t = pse_test::random_points(300, {2.0, 2.0, 2.0}, 63);
  for (auto* v : {&f, &t})
    for (auto& c : *v) c -= 1.0;
  PseOptions o;
  o.tolerance = 1e-6;
  o.xi = 1.0;
  const PseParameters p = choose_parameters(o, 1.0, L, 300);
  detail::RealSpaceSum real(p, L, kViscosity, true, detail::PairCache::off, 0, true);
  real.set_positions(x);
  const detail::RotationRealSpaceSum rotation(p, L, kViscosity);
  std::vector<double> uc(x.size(), 0.0), wc(x.size(), 0.0), ud(x.size(), 0.0), wd(x.size(), 0.0);
  rotation.apply(real.slot_lists(), x, f.data(), t.data(), uc.data(), wc.data());
  device_rows_on_host(rotation.table(), p, L, x, f, t, ud, wd);
  // The same pairs and per-pair terms, summed in another order.
  EXPECT_LT(pse_test::rel_l2(ud, uc), 1e-13);
  EXPECT_LT(pse_test::rel_l2(wd, wc), 1e-13);
}

namespace {

/// The CPU's pass (WaveGrid::scale_rotation_modes): line by line, the noise of each mode's pair
/// representative, rotation_mode_factors by (ix, iy, iz).
template <class Real>
void cpu_pass(const detail::ModeGeometry& g, const std::vector<double>& ck, const detail::RotationModeConstants& rc,
              std::vector<Real>& fs, std::vector<Real>& ts, bool deterministic, const detail::NoiseKey* key,
              double factor) {
  for (int ix = 0; ix < g.n[0]; ++ix)
    for (int iy = 0; iy < g.n[1]; ++iy)
      for (int iz = 0; iz < g.nzh; ++iz) {
        const std::size_t idx = (static_cast<std::size_t>(ix) * g.n[1] + iy) * g.nzh + iz;
        Real z[6];
        bool representative = true;
        if (key != nullptr) {
          std::uint64_t lin, rep;
          detail::mode_pair(ix, iy, iz, g, lin, rep);
          if constexpr (sizeof(Real) == sizeof(float)) {
            normal6f(key->seed, key->step, detail::kStreamWave, rep, z);
          } else {
            normal6(key->seed, key->step, detail::kStreamWave, rep, z);
          }
          representative = lin == rep;
        }
        detail::scale_rotation_mode(ix, iy, iz, idx, g, ck.data(), detail::rotation_mode_factors(ix, iy, iz, g, rc),
                                    fs.data(), ts.data(), deterministic, key != nullptr ? z : nullptr, representative,
                                    factor);
      }
}

template <class Real>
void expect_mode_scaling_matches() {
  const std::array<double, 3> L = {9.0, 10.0, 11.0};
  PseOptions o;
  o.tolerance = 1e-4;
  o.xi = 1.0;
  o.grid = {12, 14, 15};  // even and odd sides: Nyquist planes and the unpaired iz = nz / 2 absent
  const PseParameters p = choose_parameters(o, 1.0, L, 10);
  detail::ModeGeometry g{};
  const std::vector<double> ck = detail::wave_scaling_table(p, L, kViscosity, g);
  const double ng = static_cast<double>(g.n[0]) * g.n[1] * g.n[2];
  const detail::RotationModeConstants rc{p.radius, 1.0 / (4.0 * p.xi * p.xi), 1.0 - p.window_eta,
                                         1.0 / (kViscosity * ng), 0.0};
  std::vector<detail::RotationModeFactors> factors(g.modes);
  for (std::size_t idx = 0; idx < g.modes; ++idx) factors[idx] = detail::rotation_mode_factors_at(idx, g, rc);
  const detail::NoiseKey key{29, 4};
  for (const bool deterministic : {true, false}) {
    std::vector<Real> fs(6 * g.modes), ts(6 * g.modes);
    for (std::size_t q = 0; q < fs.size(); ++q) {
      fs[q] = static_cast<Real>(std::sin(0.37 * static_cast<double>(q)));
      ts[q] = static_cast<Real>(std::cos(0.91 * static_cast<double>(q)));
    }
    auto fd = fs, td = ts;
    cpu_pass(g, ck, rc, fs, ts, deterministic, &key, 0.7);
    for (std::size_t idx = 0; idx < g.modes; ++idx)
      detail::scale_rotation_mode_at(idx, g, ck.data(), factors.data(), fd.data(), td.data(), deterministic, true,
                                     key.seed, key.step, 0.7);
    EXPECT_EQ(fd, fs) << "deterministic " << deterministic;
    EXPECT_EQ(td, ts) << "deterministic " << deterministic;
  }
}

}  // namespace

TEST(PseRotationDeviceFunctions, ModeScalingByIndexIsTheCpuPass) {
  expect_mode_scaling_matches<double>();
  expect_mode_scaling_matches<float>();
}
