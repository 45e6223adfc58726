// rpyfmm — the rotational blocks of the PSE real-space part on the CPU (rotation_real_space_sum.hpp).
// The rows are branch-free loops over a particle's neighbour slots that GCC vectorizes with
// gathers (compiled per instruction-set level by simd_dispatch, with the pair-loop flags of
// cmake/RpyfmmPairLoops.cmake): positions, forces and torques are first gathered into slot order,
// one array per component.
#include "rotation_real_space_sum.hpp"

#include <cmath>
#include <cstdint>

#include "kernels_common.hpp"
#include "rotation_pair_device.hpp"
#include "rpyfmm/core/simd_dispatch.hpp"

namespace rpyfmm::rpy::pse::detail {

namespace {

/// Loops below this many list entries run serially.
constexpr std::size_t kParallelPairs = 16384;

/// Positions, forces and torques by slot, one array per component.
struct RotationSlots {
  const double* x[3];
  const double* f[3];
  const double* t[3];
};

/// The table's interpolation data (PseRotationTable) and the box.
struct RotationFrame {
  RotationTableView table;
  double L[3], inv_L[3];
};

/// One row without the self block: u += sum_q c (T_q x e), w += sum_q c (F_q x e) + h T_q +
/// k (e . T_q) e over the neighbour slots nb[0 .. count) of the particle at xi (docs/theory/pse.md
/// "Rotation"; rotation_pair_terms, which the CUDA rows share).
void rotation_row(const int* nb, std::size_t count, const double xi[3], const RotationSlots& s, const RotationFrame& fr,
                  double u[3], double w[3]) {
  simd_dispatch([=]() RPYFMM_SIMD_BODY {
    double ux = 0.0, uy = 0.0, uz = 0.0, wx = 0.0, wy = 0.0, wz = 0.0;
#pragma omp simd reduction(+ : ux, uy, uz, wx, wy, wz)
    for (std::size_t q = 0; q < count; ++q) {
      const auto j = static_cast<std::size_t>(nb[q]);
      const double dx = minimum_image(xi[0] - s.x[0][j], fr.L[0], fr.inv_L[0]);
      const double dy = minimum_image(xi[1] - s.x[1][j], fr.L[1], fr.inv_L[1]);
      const double dz = minimum_image(xi[2] - s.x[2][j], fr.L[2], fr.inv_L[2]);
      const RotationPairTerms p =
          rotation_pair_terms(dx, dy, dz, s.f[0][j], s.f[1][j], s.f[2][j], s.t[0][j], s.t[1][j], s.t[2][j], fr.table);
      ux += p.ux;
      uy += p.uy;
      uz += p.uz;
      wx += p.wx;
      wy += p.wy;
      wz += p.wz;
    }
    u[0] = ux;
    u[1] = uy;
    u[2] = uz;
    w[0] = wx;
    w[1] = wy;
    w[2] = wz;
  });
}

}  // namespace

RotationRealSpaceSum::RotationRealSpaceSum(const PseParameters& p, const std::array<double, 3>& box, double viscosity)
    : box_(box), inv_mu_(1.0 / viscosity), table_(p.xi, p.radius, p.r_cut, p.tolerance / 10.0) {}

void RotationRealSpaceSum::apply(const RealSpaceSum::SlotLists& lists, std::span<const double> x, const double* forces,
                                 const double* torques, double* velocities, double* angular) const {
  const std::size_t n = lists.order.size();
  // x, y, z, fx, fy, fz, tx, ty, tz by slot.
  work_.resize(9 * n);
  for (std::size_t s = 0; s < n; ++s) {
    const std::size_t i = lists.order[s];
    for (int c = 0; c < 3; ++c) {
      work_[c * n + s] = x[3 * i + c];
      work_[(3 + c) * n + s] = forces[3 * i + c];
      work_[(6 + c) * n + s] = torques[3 * i + c];
    }
  }
  const double* wk = work_.data();
  const RotationSlots slots{
      {wk, wk + n, wk + 2 * n}, {wk + 3 * n, wk + 4 * n, wk + 5 * n}, {wk + 6 * n, wk + 7 * n, wk + 8 * n}};
  const RotationFrame frame{{table_.data(), table_.inv_dr(), table_.unit_c(), table_.unit_hk()},
                            {box_[0], box_[1], box_[2]},
                            {1.0 / box_[0], 1.0 / box_[1], 1.0 / box_[2]}};
  const double self = table_.self();
#pragma omp parallel for schedule(dynamic, 64) if (lists.list.size() >= kParallelPairs)
  for (std::int64_t ss = 0; ss < static_cast<std::int64_t>(n); ++ss) {
    const auto s = static_cast<std::size_t>(ss);
    const std::size_t i = lists.order[s];
    const double xi[3] = {slots.x[0][s], slots.x[1][s], slots.x[2][s]};
    double u[3], w[3];
    rotation_row(lists.list.data() + lists.begin[s], lists.begin[s + 1] - lists.begin[s], xi, slots, frame, u, w);
    for (int c = 0; c < 3; ++c) {
      velocities[3 * i + c] += inv_mu_ * u[c];
      angular[3 * i + c] += inv_mu_ * (self * torques[3 * i + c] + w[c]);
    }
  }
}

}  // namespace rpyfmm::rpy::pse::detail
