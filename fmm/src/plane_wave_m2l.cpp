// The plane-wave M2L of one level with merge-and-shift (docs/theory/fmm.md; Guan, dissertation,
// Algorithm 1 step 4 and Theorems 2.2.7-2.2.9; Cheng, Greengard & Rokhlin, J. Comput. Phys. 155
// (1999) §3-§4).
//
// For each of the three frame pairs (up/down along z, y and x): every box of the level turns its
// multipole into outgoing plane waves of both directions; every parent then merges the waves of
// its colleagues' children, shifted to a common centre (the parent's child 0), into one sum per
// group of receiving children, and each receiving child adds the groups that reach it, shifts the
// sum to its own centre and converts it into a local expansion.
#include <algorithm>
#include <array>
#include <vector>

#include "fmm_stages.hpp"
#include "planewave_kernels.hpp"

namespace rpyfmm::fmm::detail {
namespace {

// Plane waves of one frame pair for every box of a level: box b's up-going values at
// waves[(b - level begin) * 2 wave_stride], its down-going ones wave_stride further.
struct LevelWaves {
  int level_begin = 0;
  std::size_t wave_stride = 0;  // sum_physical() x nd: one direction of one box
  std::vector<cplx> values;
  [[nodiscard]] const cplx* of(int b, int sign) const noexcept {
    return &values[std::size_t(b - level_begin) * 2 * wave_stride + (sign > 0 ? 0 : wave_stride)];
  }
};

// M2X (Guan, Theorem 2.2.7): each box's multipole, scaled to unit side, rotated into frame f and
// turned into plane waves of both directions. nd > 1 takes the densities in vector lanes
// (planewave_batch.cpp).
void outgoing_waves(const Evaluation& ev, int l, int f, LevelWaves& lw) {
  const auto& boxes = ev.boxes;
  const auto& pw = *ev.plan.pw;
  const int nc = ev.nc, sumM = pw.sum_physical(), sumK = pw.sum_fourier();
  const std::size_t nd = ev.nd, stride = ev.stride, wave_stride = lw.wave_stride;
  const double s = ev.tree.side(l);
  const int lb = ev.tree.level_begin(l), le = ev.tree.level_end(l);
#pragma omp parallel if (std::size_t(le - lb) >= kMinParallel)
  {
    std::vector<cplx> Mt(nc), Mr(nc), Mw(nc), Fu(sumK), Fd(sumK);
    PlaneWave::LaneWork lanes;
#pragma omp for schedule(dynamic, 16)
    for (int b = lb; b < le; ++b) {
      if (boxes[b].nsrc() == 0) continue;
      cplx* W = &lw.values[std::size_t(b - lb) * 2 * wave_stride];
      if (nd > 1) {
        for (std::size_t d0 = 0; d0 < nd; d0 += PlaneWave::kDensityLanes) {
          const int nl = int(std::min<std::size_t>(PlaneWave::kDensityLanes, nd - d0));
          pw.multipole_to_waves(f, &ev.mp[std::size_t(b) * stride + d0 * nc], std::size_t(nc), nl, 1.0 / s,
                                W + d0 * sumM, W + wave_stride + d0 * sumM, std::size_t(sumM), lanes);
        }
        continue;
      }
      const cplx* Mh = &ev.mp[std::size_t(b) * stride];  // nd = 1
      for (int i = 0; i < nc; ++i) Mt[i] = Mh[i] / s;    // unit-frame multipole
      pw.to_frame(f, Mt.data(), Mr.data(), Mw.data());
      pw.m2f(Mr.data(), Fu.data(), Fd.data());
      pw.f2p(Fu.data(), W);
      pw.f2p(Fd.data(), W + wave_stride);
    }
  }
}

// One merged sum: the shifted waves of the source boxes that reach the same set of children
// (mask) in the same direction (sign).
struct MergedWaves {
  int sign;
  unsigned mask;
  std::vector<cplx> v;
};

// Thread-local work of the receiving side. G, L: the nd = 1 path.
struct ReceiveWork {
  ReceiveWork(std::size_t wave_stride, int sumK, int nc) : V2(2 * wave_stride), Gu(sumK), Gd(sumK), Lf(nc), Lb(nc) {}
  std::vector<MergedWaves> merged;
  std::size_t nmerged = 0;
  std::vector<cplx> V2, Gu, Gd, Lf, Lb;
  PlaneWave::LaneWork lanes;
};

// X2X, merge (Guan, Theorem 2.2.8): the waves of the children of parent P0's colleagues, each
// shifted from its centre to that of P0's child 0 (offset -a) and added to the sum of its merge
// group (merge_groups(): the children of P0 it reaches in this direction).
void merge_colleague_waves(const Evaluation& ev, int P0, int f, const LevelWaves& lw, ReceiveWork& rw) {
  const auto& boxes = ev.boxes;
  const auto& pw = *ev.plan.pw;
  const auto& groups = merge_groups();
  const auto& par = boxes[P0];
  const std::size_t sumM = std::size_t(pw.sum_physical()), nd = ev.nd, wave_stride = lw.wave_stride;
  auto& accs = rw.merged;
  std::size_t& nacc = rw.nmerged;
  nacc = 0;
  for (int C : ev.tree.colleagues().of(P0))
    for (int e : boxes[C].child) {
      if (e < 0 || boxes[e].nsrc() == 0) continue;
      const int ax = int(boxes[e].ix - 2 * par.ix), ay = int(boxes[e].iy - 2 * par.iy),
                az = int(boxes[e].iz - 2 * par.iz);
      const MergeGroup g = groups[merge_position(ax, ay, az)][f];
      if (g.mask == 0) continue;
      std::size_t k = 0;
      while (k < nacc && !(accs[k].sign == g.sign && accs[k].mask == g.mask)) ++k;
      if (k == nacc) {
        if (accs.size() <= nacc) accs.push_back({0, 0, {}});
        accs[k].sign = g.sign;
        accs[k].mask = g.mask;
        accs[k].v.assign(wave_stride, cplx(0.0));
        ++nacc;
      }
      const auto dp = PlaneWave::frame_offset(f, {-ax, -ay, -az});
      const cplx* sh = g.sign > 0 ? pw.shift(dp[0], dp[1], dp[2]) : pw.shift(-dp[0], -dp[1], -dp[2]);
      shift_accumulate(sumM, nd, sh, lw.of(e, g.sign), accs[k].v.data());
    }
}

// X2X, shift (Guan, Theorem 2.2.8): the merged sums that reach child o of the parent, added up per
// direction (V2: up, then down) and shifted from child 0's centre to child o's. Returns which
// directions received waves; with nd = 1 their Fourier coefficients go to Gu, Gd.
std::array<bool, 2> incoming_waves(const Evaluation& ev, int f, int o, std::size_t wave_stride, ReceiveWork& rw) {
  const auto& pw = *ev.plan.pw;
  const int sumM = pw.sum_physical(), sumK = pw.sum_fourier();
  const std::size_t nd = ev.nd;
  std::array<bool, 2> got = {false, false};
  for (int sgn = 0; sgn < 2; ++sgn) {
    const int sign = sgn == 0 ? 1 : -1;
    cplx* V = rw.V2.data() + sgn * wave_stride;
    std::fill(V, V + wave_stride, cplx(0.0));
    for (std::size_t k = 0; k < rw.nmerged; ++k) {
      if (rw.merged[k].sign != sign || !(rw.merged[k].mask & (1u << o))) continue;
      got[sgn] = true;
      accumulate(wave_stride, rw.merged[k].v.data(), V);
    }
    cplx* G = sgn == 0 ? rw.Gu.data() : rw.Gd.data();
    if (!got[sgn]) {
      if (nd == 1) std::fill(G, G + sumK, cplx(0.0));
      continue;
    }
    const auto dp = PlaneWave::frame_offset(f, {o & 1, (o >> 1) & 1, (o >> 2) & 1});
    const cplx* sh = sign > 0 ? pw.shift(dp[0], dp[1], dp[2]) : pw.shift(-dp[0], -dp[1], -dp[2]);
    shift_in_place(std::size_t(sumM), nd, sh, V);
    if (nd == 1) pw.p2f(V, G);
  }
  return got;
}

// X2L (Guan, Theorem 2.2.9): the incoming waves of box c converted into a local expansion, rotated
// back from frame f and added to c's local expansion. nd > 1 takes the densities in vector lanes.
void waves_to_local(Evaluation& ev, int f, int c, std::array<bool, 2> got, std::size_t wave_stride, ReceiveWork& rw) {
  const auto& pw = *ev.plan.pw;
  const int nc = ev.nc, sumM = pw.sum_physical();
  const std::size_t nd = ev.nd, stride = ev.stride;
  if (nd > 1) {
    for (std::size_t d0 = 0; d0 < nd; d0 += PlaneWave::kDensityLanes) {
      const int nl = int(std::min<std::size_t>(PlaneWave::kDensityLanes, nd - d0));
      pw.waves_to_local(f, got[0] ? rw.V2.data() + d0 * sumM : nullptr,
                        got[1] ? rw.V2.data() + wave_stride + d0 * sumM : nullptr, std::size_t(sumM), nl,
                        &ev.lp[std::size_t(c) * stride + d0 * nc], std::size_t(nc), rw.lanes);
    }
    return;
  }
  pw.f2l(rw.Gu.data(), rw.Gd.data(), rw.Lf.data());  // nd = 1
  pw.from_frame(f, rw.Lf.data(), rw.Lb.data());
  cplx* out = &ev.lp[std::size_t(c) * stride];
  for (int i = 0; i < nc; ++i) out[i] += rw.Lb[i];
}

// The receiving side for every parent on level l - 1 with children on level l.
void receive_waves(Evaluation& ev, int l, int f, const LevelWaves& lw) {
  const auto& boxes = ev.boxes;
  const auto& pw = *ev.plan.pw;
  const int pb = ev.tree.level_begin(l - 1), pe = ev.tree.level_end(l - 1);
#pragma omp parallel if (std::size_t(pe - pb) >= kMinParallel)
  {
    ReceiveWork rw(lw.wave_stride, pw.sum_fourier(), ev.nc);
#pragma omp for schedule(dynamic, 4)
    for (int P0 = pb; P0 < pe; ++P0) {
      const auto& par = boxes[P0];
      if (par.leaf || par.ntgt() == 0) continue;
      merge_colleague_waves(ev, P0, f, lw, rw);
      if (rw.nmerged == 0) continue;
      for (int o = 0; o < 8; ++o) {
        const int c = par.child[o];
        if (c < 0 || boxes[c].ntgt() == 0) continue;
        const auto got = incoming_waves(ev, f, o, lw.wave_stride, rw);
        if (!got[0] && !got[1]) continue;
        ev.has_local[c] = 1;
        waves_to_local(ev, f, c, got, lw.wave_stride, rw);
      }
    }
  }
}

}  // namespace

void plane_wave_m2l(Evaluation& ev, int l) {
  LevelWaves lw;
  lw.level_begin = ev.tree.level_begin(l);
  lw.wave_stride = std::size_t(ev.plan.pw->sum_physical()) * ev.nd;
  lw.values.resize(std::size_t(ev.tree.level_end(l) - lw.level_begin) * 2 * lw.wave_stride);
  for (int f = 0; f < 3; ++f) {  // frame pairs: up/down along z, y, x
    outgoing_waves(ev, l, f, lw);
    receive_waves(ev, l, f, lw);
  }
}

}  // namespace rpyfmm::fmm::detail
