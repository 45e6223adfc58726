// The host-device functions of the CUDA rotation path (rpy/src/pse/rotation_pair_device.hpp,
// rpy/src/pse/rotation_modes.hpp), run on the host against the CPU operator's code: the device
// rows (per pair and per row, over the lists or every pair within r_cut) give the CPU rows'
// rotational real-space product and its sampler scaling, and the per-mode scaling by linear index
// with its own noise draw gives the CPU's line-by-line pass bit for bit.
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

/// Host copies of the device rows' inputs and outputs in slot order (3 doubles per particle), with
/// their RotationRows for torque and angular scale s.
struct SlotRows {
  std::vector<double> x, f, t, u, w;
  detail::RotationRows rows{};

  SlotRows(const detail::RealSpaceSum::SlotLists& lists, const PseRotationTable& tab, const std::array<double, 3>& L,
           const std::vector<double>& xin, const std::vector<double>& fin, const std::vector<double>& tin, double s)
      : x(xin.size()), f(xin.size()), t(xin.size()), u(xin.size(), 0.0), w(xin.size(), 0.0) {
    for (std::size_t slot = 0; slot < lists.order.size(); ++slot)
      for (int c = 0; c < 3; ++c) {
        x[3 * slot + c] = xin[3 * lists.order[slot] + c];
        f[3 * slot + c] = fin[3 * lists.order[slot] + c];
        t[3 * slot + c] = tin[3 * lists.order[slot] + c];
      }
    rows = {x.data(),   f.data(),           t.data(),
            u.data(),   w.data(),           {tab.data(), tab.inv_dr(), tab.unit_c(), tab.unit_hk()},
            tab.self(), 1.0 / kViscosity,   s,
            s,          {L[0], L[1], L[2]}, {1.0 / L[0], 1.0 / L[1], 1.0 / L[2]}};
  }
  /// out (input order) = v (slot order).
  static std::vector<double> to_input(const detail::RealSpaceSum::SlotLists& lists, const std::vector<double>& v) {
    std::vector<double> out(v.size());
    for (std::size_t slot = 0; slot < lists.order.size(); ++slot)
      for (int c = 0; c < 3; ++c) out[3 * lists.order[slot] + c] = v[3 * slot + c];
    return out;
  }
};

/// The CUDA list kernel's rows on the host: slot i over its neighbour list.
void list_rows(const detail::RealSpaceSum::SlotLists& lists, const detail::RotationRows& r) {
  for (std::size_t i = 0; i < lists.order.size(); ++i) {
    double acc[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    const double xi[3] = {r.x[3 * i], r.x[3 * i + 1], r.x[3 * i + 2]};
    for (std::size_t q = lists.begin[i]; q < lists.begin[i + 1]; ++q)
      detail::rotation_pair_add(r, lists.list[q], xi, acc);
    detail::rotation_row_store(r, static_cast<int>(i), acc);
  }
}

/// The CUDA cell-list kernel's rows on the host: every slot j != i with |d|^2 < rc2.
void all_pair_rows(std::size_t n, double rc2, const detail::RotationRows& r) {
  for (std::size_t i = 0; i < n; ++i) {
    double acc[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    const double xi[3] = {r.x[3 * i], r.x[3 * i + 1], r.x[3 * i + 2]};
    for (std::size_t j = 0; j < n; ++j) {
      if (j == i) continue;
      double d[3];
      detail::rotation_displacement(r, static_cast<int>(j), xi, d);
      if (d[0] * d[0] + d[1] * d[1] + d[2] * d[2] < rc2) detail::rotation_pair_add(r, static_cast<int>(j), xi, acc);
    }
    detail::rotation_row_store(r, static_cast<int>(i), acc);
  }
}

}  // namespace

// The device rows (over the host's lists and over every pair within r_cut, as the device cell list
// finds them) give the CPU rows' product, and with scale a the CPU's S M_r S of the split sampler
// (torques times a in, angular velocities times a out). The same pairs and per-pair terms summed in
// another order: 1e-13 relative.
TEST(PseRotationDeviceFunctions, DeviceRowsGiveTheCpuRows) {
  const std::array<double, 3> L = {14.0, 12.0, 15.0};
  const double a = 0.9;
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
  const PseParameters p = choose_parameters(o, a, L, 300);
  detail::RealSpaceSum real(p, L, kViscosity, true, detail::PairCache::off, 0, true);
  real.set_positions(x);
  const auto lists = real.slot_lists();
  const detail::RotationRealSpaceSum rotation(p, L, kViscosity);
  for (const double s : {1.0, a}) {
    SCOPED_TRACE(s == 1.0 ? "product" : "sampler scaling");
    std::vector<double> ts(t.size());
    for (std::size_t k = 0; k < t.size(); ++k) ts[k] = s * t[k];
    std::vector<double> uc(x.size(), 0.0), wc(x.size(), 0.0);
    rotation.apply(lists, x, f.data(), ts.data(), uc.data(), wc.data());
    for (auto& v : wc) v *= s;
    SlotRows by_list(lists, rotation.table(), L, x, f, t, s), by_pair(lists, rotation.table(), L, x, f, t, s);
    list_rows(lists, by_list.rows);
    all_pair_rows(lists.order.size(), p.r_cut * p.r_cut, by_pair.rows);
    for (const SlotRows* rows : {&by_list, &by_pair}) {
      EXPECT_LT(pse_test::rel_l2(SlotRows::to_input(lists, rows->u), uc), 1e-13);
      EXPECT_LT(pse_test::rel_l2(SlotRows::to_input(lists, rows->w), wc), 1e-13);
    }
  }
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
