// The exact near field of FmmRpy (fmm_near_field.hpp): the leaf pairs of a near field in the
// colour schedule of near_schedule.hpp, sources gathered leaf by leaf (near_sources.hpp) and summed
// by the vectorized pair kernels (fmm_near_kernels.hpp, rotation_pair_sums.hpp).
#include "fmm_near_field.hpp"

#include <cstdint>
#include <span>
#include <vector>

#include "fmm_near_kernels.hpp"
#include "near_sources.hpp"
#include "rotation_pair_sums.hpp"
#include "rpyfmm/rpy/rpy_kernel.hpp"
#include "rpyfmm/rpy/rpy_rotation_kernel.hpp"

namespace rpyfmm::rpy::detail {
namespace {

// Trees with fewer leaves evaluate each directed leaf pair on its own (one colour, parallel over
// target leaves): with few leaves per colour the symmetric schedule would leave threads idle.
// A property of the tree only, never of the thread count, so results stay thread-invariant.
constexpr std::size_t kSymmetricMinLeaves = 64;

}  // namespace

NearSchedule near_schedule_for(const fmm::NearField& near, bool same_points) {
  return make_near_schedule(near.pairs, near.num_leaves(), same_points && near.num_leaves() >= kSymmetricMinLeaves);
}

namespace {

// Stored pair scalars of one target against gathered sources (block products).
struct PairScalars {
  std::vector<double> buf;
  double *dx = nullptr, *dy = nullptr, *dz = nullptr, *fs = nullptr, *gr = nullptr;
  void resize(std::size_t m) {
    buf.resize(5 * m);
    dx = buf.data();
    dy = dx + m;
    dz = dy + m;
    fs = dz + m;
    gr = fs + m;
  }
};

// What every near-field task reads and writes.
struct NearContext {
  const fmm::NearField& near;
  std::span<const double> x, a;
  const double* forces;
  double* velocities;
  std::size_t n, nrhs;
  double inv_eta;
  bool equal;
  bool self_terms;

  [[nodiscard]] const double* force(std::size_t k, std::size_t i) const { return forces + 3 * n * k + 3 * i; }
  void add_velocity(std::size_t k, std::size_t i, const double u[3]) const {
    double* ui = velocities + 3 * n * k + 3 * i;
    ui[0] += inv_eta * u[0];
    ui[1] += inv_eta * u[1];
    ui[2] += inv_eta * u[2];
  }
};

// The targets of `leaf` against gathered sources, for every right-hand side.
//  - kBothWays = false: one-sided sources (the leaf itself among them: the self pair is skipped
//    inside the kernels), plus the self term M_ii = I / (6 pi eta a_i) where asked.
//  - kBothWays = true: the sources of the leaf's symmetric partners (other leaves). Each pair
//    block is evaluated once for both directions (M_ji = M_ij); the partners' velocities are
//    accumulated in src.u and added once at the end. (FmmRpy evaluates at its own points, so a
//    leaf's sources are its targets and src.id indexes velocities too.)
// Block products (nrhs > 1) compute the pair scalars once per target and accumulate them per
// rhs: the geometry is most of the work.
template <bool kBothWays>
void leaf_block(const NearContext& ctx, std::uint32_t leaf, GatheredSources& src, PairScalars& ps) {
  const std::size_t m = src.size();
  const double* sa = ctx.equal ? nullptr : src.a.data();
  const bool block = ctx.nrhs > 1;
  if constexpr (kBothWays) src.u.assign(3 * m * ctx.nrhs, 0.0);
  if (block) ps.resize(m);
  for (std::size_t i : ctx.near.targets(leaf)) {
    const double xi = ctx.x[3 * i], yi = ctx.x[3 * i + 1], zi = ctx.x[3 * i + 2], ai = ctx.a[i];
    if (block) {
      near_pair_scalars(m, src.x.data(), src.y.data(), src.z.data(), sa, src.id.data(), xi, yi, zi, ai, i, ps.dx, ps.dy,
                        ps.dz, ps.fs, ps.gr);
    }
    for (std::size_t k = 0; k < ctx.nrhs; ++k) {
      const double *fx = src.forces(k, 0), *fy = src.forces(k, 1), *fz = src.forces(k, 2);
      const double* fi = ctx.force(k, i);
      double u[3];
      if constexpr (kBothWays) {
        double *ux = src.velocities(k, 0), *uy = src.velocities(k, 1), *uz = src.velocities(k, 2);
        if (block) {
          near_accumulate_symmetric(m, ps.dx, ps.dy, ps.dz, ps.fs, ps.gr, fx, fy, fz, fi, ux, uy, uz, u);
        } else {
          near_pair_sum_symmetric(m, src.x.data(), src.y.data(), src.z.data(), sa, fx, fy, fz, xi, yi, zi, ai, fi, ux,
                                  uy, uz, u);
        }
      } else {
        if (block) {
          near_accumulate(m, ps.dx, ps.dy, ps.dz, ps.fs, ps.gr, fx, fy, fz, u);
        } else {
          near_pair_sum(m, src.x.data(), src.y.data(), src.z.data(), sa, src.id.data(), fx, fy, fz, xi, yi, zi, ai, i,
                        u);
        }
        if (ctx.self_terms) {
          const double self = rpy_self(ai);
          for (int c = 0; c < 3; ++c) u[c] += self * fi[c];
        }
      }
      ctx.add_velocity(k, i, u);
    }
  }
  if constexpr (kBothWays) {
    for (std::size_t k = 0; k < ctx.nrhs; ++k) {
      const double *ux = src.velocities(k, 0), *uy = src.velocities(k, 1), *uz = src.velocities(k, 2);
      for (std::size_t q = 0; q < m; ++q) {
        const double u[3] = {ux[q], uy[q], uz[q]};
        ctx.add_velocity(k, src.id[q], u);
      }
    }
  }
}

}  // namespace

void add_near_velocities(const NearPoints& points, const double* forces, double* velocities, std::size_t nrhs,
                         double inv_eta) {
  const NearContext ctx{points.near, points.x, points.a, forces,       velocities,
                        points.n,    nrhs,     inv_eta,  points.equal, points.self_terms};
  struct ThreadState {
    GatheredSources src;
    PairScalars ps;
  };
  for_each_near_task<ThreadState>(points.schedule,
                                  [&](ThreadState& state, std::uint32_t leaf, std::span<const std::uint32_t> one,
                                      std::span<const std::uint32_t> partners) {
                                    state.src.gather(ctx.near, one, ctx.x, ctx.a, forces, ctx.n, nrhs);
                                    leaf_block<false>(ctx, leaf, state.src, state.ps);
                                    // All symmetric partners at once: one long pair loop per target.
                                    if (!partners.empty()) {
                                      state.src.gather(ctx.near, partners, ctx.x, ctx.a, forces, ctx.n, nrhs);
                                      leaf_block<true>(ctx, leaf, state.src, state.ps);
                                    }
                                  });
}

namespace {

// What every near-field task reads and writes. Sources are gathered with the loads [F; T]
// (two right-hand sides of GatheredSources: forces, then torques); u and w (3n each, times eta)
// receive the near-field sums.
struct GrandNearContext {
  const fmm::NearField& near;
  std::span<const double> x, a;
  const double* loads;  // 6n: F then T
  double *u, *w;
  std::size_t n;
  bool equal;
  bool self_terms;

  [[nodiscard]] GrandTarget target(std::size_t i) const {
    const double* f = loads + 3 * i;
    const double* t = loads + 3 * n + 3 * i;
    return {x[3 * i], x[3 * i + 1], x[3 * i + 2], a[i], i, {f[0], f[1], f[2]}, {t[0], t[1], t[2]}};
  }
  void add(std::size_t i, const GrandSums& s) const {
    for (int c = 0; c < 3; ++c) {
      u[3 * i + c] += s.u[c];
      w[3 * i + c] += s.w[c];
    }
  }
};

GrandSources view(const GatheredSources& src, bool equal) {
  return {src.size(),       src.x.data(),     src.y.data(),     src.z.data(),     equal ? nullptr : src.a.data(),
          src.id.data(),    src.forces(0, 0), src.forces(0, 1), src.forces(0, 2), src.forces(1, 0),
          src.forces(1, 1), src.forces(1, 2)};
}

// The leaf's targets against one-sided sources (the leaf itself among them), plus the self terms
// F_i / (6 pi eta a_i) and T_i / (8 pi eta a_i^3) where asked: with kTranslation the grand blocks
// (grand_pair_sum), without it the rotational couplings alone and no translational self term
// (rotation_pair_sum).
template <bool kTranslation>
void one_sided_block(const GrandNearContext& ctx, std::uint32_t leaf, const GatheredSources& src) {
  const GrandSources s = view(src, ctx.equal);
  for (std::size_t i : ctx.near.targets(leaf)) {
    const GrandTarget t = ctx.target(i);
    GrandSums sums{};
    if constexpr (kTranslation) {
      grand_pair_sum(s, t, sums);
    } else {
      rotation_pair_sum(s, t, sums);
    }
    if (ctx.self_terms) {
      const double self_t = kTranslation ? rpy_self(t.a) : 0.0, self_r = rpy_rotation_self(t.a);
      for (int c = 0; c < 3; ++c) {
        if constexpr (kTranslation) sums.u[c] += self_t * t.f[c];
        sums.w[c] += self_r * t.t[c];
      }
    }
    ctx.add(i, sums);
  }
}

// The leaf's targets against the sources of its symmetric partners, both directions at once;
// the partners' sums are accumulated in src.u and added once at the end.
void symmetric_block(const GrandNearContext& ctx, std::uint32_t leaf, GatheredSources& src) {
  const std::size_t m = src.size();
  src.u.assign(6 * m, 0.0);
  const GrandSources s = view(src, ctx.equal);
  const GrandAccumulators acc{{src.velocities(0, 0), src.velocities(0, 1), src.velocities(0, 2)},
                              {src.velocities(1, 0), src.velocities(1, 1), src.velocities(1, 2)}};
  for (std::size_t i : ctx.near.targets(leaf)) {
    GrandSums sums{};
    grand_pair_sum_symmetric(s, ctx.target(i), acc, sums);
    ctx.add(i, sums);
  }
  for (std::size_t q = 0; q < m; ++q) {
    const GrandSums back{{acc.u[0][q], acc.u[1][q], acc.u[2][q]}, {acc.w[0][q], acc.w[1][q], acc.w[2][q]}};
    ctx.add(src.id[q], back);
  }
}

}  // namespace

void add_grand_near_field(const NearPoints& points, const double* loads, double* u, double* w) {
  const GrandNearContext ctx{points.near, points.x, points.a, loads, u, w, points.n, points.equal, points.self_terms};
  for_each_near_task<GatheredSources>(points.schedule,
                                      [&](GatheredSources& src, std::uint32_t leaf, std::span<const std::uint32_t> one,
                                          std::span<const std::uint32_t> partners) {
                                        src.gather(ctx.near, one, ctx.x, ctx.a, loads, ctx.n, 2);
                                        one_sided_block<true>(ctx, leaf, src);
                                        if (!partners.empty()) {
                                          src.gather(ctx.near, partners, ctx.x, ctx.a, loads, ctx.n, 2);
                                          symmetric_block(ctx, leaf, src);
                                        }
                                      });
}

void add_rotation_near_field(const NearPoints& points, const double* loads, double* u, double* w) {
  const GrandNearContext ctx{points.near, points.x, points.a, loads, u, w, points.n, points.equal, points.self_terms};
  for_each_near_task<GatheredSources>(points.schedule,
                                      [&](GatheredSources& src, std::uint32_t leaf, std::span<const std::uint32_t> one,
                                          std::span<const std::uint32_t> /*partners: none*/) {
                                        src.gather(ctx.near, one, ctx.x, ctx.a, loads, ctx.n, 2);
                                        one_sided_block<false>(ctx, leaf, src);
                                      });
}

}  // namespace rpyfmm::rpy::detail
