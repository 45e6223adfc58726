// The tree passes of the Laplace FMM around the plane-wave M2L (fmm_stages.hpp): sorting, P2M and
// M2M up the tree, L2L and X-list P2L down it, and L2P, W-list M2P and the direct sums at the
// leaves (docs/theory/fmm.md; Guan, dissertation, Algorithm 1 and Theorems 2.2.2-2.2.5;
// Cheng, Greengard & Rokhlin, J. Comput. Phys. 155 (1999) §4).
#include <algorithm>
#include <array>
#include <span>
#include <vector>

#include "fmm_stages.hpp"
#include "rpyfmm/fmm/direct_simd.hpp"

namespace rpyfmm::fmm::detail {

Evaluation::Evaluation(const LaplaceFmm::Plan& plan_, std::size_t nd_, std::span<const unsigned> outputs_)
    : plan(plan_),
      tree(plan_.tree),
      boxes(plan_.tree.boxes()),
      p(plan_.p),
      nc(ncoef(plan_.p)),
      nd(nd_),
      N(plan_.n),
      M(plan_.m),
      stride(nd_ * std::size_t(ncoef(plan_.p))),
      requested(outputs_),
      outputs(outputs_.begin(), outputs_.end()),
      mp(boxes.size() * stride),
      lp(boxes.size() * stride),
      has_local(boxes.size(), 0),
      leaf_seconds(plan_.tree.leaves().size(), 0.0) {
  for (std::size_t d = 0; d < nd; ++d) {
    const unsigned f = outputs[d];
    if (f != kCurlGradDiv && !(f & kGradDiv)) continue;
    groups.push_back(d);
    combined_per_coef += combined_per_group(f);
    for (std::size_t k = d; k < d + 3; ++k)
      outputs[k] = f == kCurlGradDiv ? kGradient | kHessian : (outputs[k] & (kPotential | kGradient)) | kHessian;
    d += 2;
  }
  for (unsigned f : outputs) any_flags |= f;
  uniform_flags = std::all_of(outputs.begin(), outputs.end(), [&](unsigned f) { return f == outputs[0]; });
}

void sort_charges(Evaluation& ev, std::span<const double> charges) {
  const std::size_t N = ev.N, nd = ev.nd;
  ev.qs.resize(nd * N);
  auto& qs = ev.qs;
  const auto& sperm = ev.tree.source_order();
#pragma omp parallel for if (N >= 4096) schedule(static)
  for (std::size_t j = 0; j < N; ++j)
    for (std::size_t d = 0; d < nd; ++d) qs[d * N + j] = charges[d * N + sperm[j]];
  ev.res.assign(nd * ev.M * result_width, 0.0);
}

namespace {

// Offsets (x - c) / s of the points [begin, min(begin + kL2PLanes, end)) from a box centre c in
// units of its side s (inv_s = 1 / s), into lanes u{x,y,z}; returns their number.
inline int scaled_offsets(const std::vector<double>& x, const std::vector<double>& y, const std::vector<double>& z,
                          std::size_t begin, std::size_t end, const std::array<double, 3>& c, double inv_s, double* ux,
                          double* uy, double* uz) noexcept {
  const int n = int(std::min<std::size_t>(kL2PLanes, end - begin));
  for (int t = 0; t < n; ++t) {
    ux[t] = (x[begin + t] - c[0]) * inv_s;
    uy[t] = (y[begin + t] - c[1]) * inv_s;
    uz[t] = (z[begin + t] - c[2]) * inv_s;
  }
  return n;
}

}  // namespace

// P2M (Guan, Theorem 2.2.2; docs/theory/fmm.md): sources taken kL2PLanes at a time, their offsets
// from the box centre in units of the box side.
void form_leaf_multipoles(Evaluation& ev) {
  const auto& P = ev.plan;
  const auto& tree = ev.tree;
  const auto& boxes = ev.boxes;
  const auto& H = *P.H;
  const int p = ev.p;
  const std::size_t N = ev.N, nd = ev.nd, stride = ev.stride;
  const auto& leaves = tree.leaves();
#pragma omp parallel if (leaves.size() >= kMinParallel)
  {
    std::vector<double> scratch(2 * std::size_t(ev.nc) * kL2PLanes);
#pragma omp for schedule(dynamic, 8)
    for (std::size_t i = 0; i < leaves.size(); ++i) {
      const int b = leaves[i];
      const auto& bx = boxes[b];
      if (bx.nsrc() == 0 || bx.level < 2) continue;
      const auto c = tree.center(b);
      const double inv_s = 1.0 / tree.side(bx.level);
      for (std::size_t j0 = bx.src_begin; j0 < bx.src_end; j0 += kL2PLanes) {
        double ux[kL2PLanes], uy[kL2PLanes], uz[kL2PLanes];
        const int np = scaled_offsets(P.sx, P.sy, P.sz, j0, bx.src_end, c, inv_s, ux, uy, uz);
        p2m_block(p, H.regular_recurrence(), H.c_table(), np, ux, uy, uz, &ev.qs[j0], N, nd,
                  &ev.mp[std::size_t(b) * stride], scratch.data());
      }
    }
  }
}

// M2M (Guan, Theorem 2.2.4) by point-and-shoot: rotate, shift along z, rotate back
// (child_translations.cpp). Levels 0 and 1 need no multipoles: they have no V list.
void merge_child_multipoles(Evaluation& ev) {
  const auto& tree = ev.tree;
  const auto& boxes = ev.boxes;
  const auto& ct = *ev.plan.ct;
  const std::size_t nd = ev.nd, stride = ev.stride, nc = std::size_t(ev.nc);
  auto& mp = ev.mp;
  for (int l = tree.nlevels() - 2; l >= 2; --l) {
#pragma omp parallel if (std::size_t(tree.level_end(l) - tree.level_begin(l)) >= kMinParallel)
    {
      std::vector<cplx> work(2 * nc);
#pragma omp for schedule(dynamic, 8)
      for (int b = tree.level_begin(l); b < tree.level_end(l); ++b) {
        const auto& bx = boxes[b];
        if (bx.leaf || bx.nsrc() == 0) continue;
        for (int o = 0; o < 8; ++o) {
          const int c = bx.child[o];
          if (c < 0 || boxes[c].nsrc() == 0) continue;
          for (std::size_t d = 0; d < nd; ++d)
            ct.m2m(o, &mp[std::size_t(c) * stride + d * nc], &mp[std::size_t(b) * stride + d * nc], work.data());
        }
      }
    }
  }
}

// L2L (Guan, Theorem 2.2.5), point-and-shoot as M2M.
void shift_parent_locals(Evaluation& ev, int l) {
  const auto& tree = ev.tree;
  const auto& boxes = ev.boxes;
  const auto& ct = *ev.plan.ct;
  const std::size_t nd = ev.nd, stride = ev.stride, nc = std::size_t(ev.nc);
  auto& lp = ev.lp;
  auto& has_local = ev.has_local;
  const int lb = tree.level_begin(l), le = tree.level_end(l);
#pragma omp parallel if (std::size_t(le - lb) >= kMinParallel)
  {
    std::vector<cplx> work(2 * nc);
#pragma omp for schedule(dynamic, 8)
    for (int b = lb; b < le; ++b) {
      const auto& bx = boxes[b];
      if (bx.ntgt() == 0 || !has_local[bx.parent]) continue;
      int oct = 0;
      for (int o = 0; o < 8; ++o)
        if (boxes[bx.parent].child[o] == b) oct = o;
      for (std::size_t d = 0; d < nd; ++d)
        ct.l2l(oct, &lp[std::size_t(bx.parent) * stride + d * nc], &lp[std::size_t(b) * stride + d * nc], work.data());
      has_local[b] = 1;
    }
  }
}

// X list, P2L (Guan, Theorem 2.2.3; Algorithm 1 step 3): boxes with few targets are left to the
// direct sums of w_list_and_direct_far, cheaper there than a local expansion.
void x_list_to_locals(Evaluation& ev, int l) {
  const auto& tree = ev.tree;
  const auto& boxes = ev.boxes;
  const auto& H = *ev.plan.H;
  const auto& sxyz = tree.sorted_sources();
  const int p = ev.p;
  const std::size_t N = ev.N, nd = ev.nd, stride = ev.stride, direct_limit = ev.plan.direct_limit;
  const int lb = tree.level_begin(l), le = tree.level_end(l);
#pragma omp parallel if (std::size_t(le - lb) >= kMinParallel)
  {
    std::vector<cplx> scratch(ncoef(p + 2));
#pragma omp for schedule(dynamic, 8)
    for (int b = lb; b < le; ++b) {
      const auto& bx = boxes[b];
      if (bx.ntgt() <= direct_limit) continue;  // few targets: direct sum in the leaf pass
      const auto c = tree.center(b);
      for (int x : tree.xlist().of(b)) {
        const auto& xb = boxes[x];
        if (xb.nsrc() == 0) continue;
        p2l(H, p, tree.side(l), c.data(), &sxyz[3 * xb.src_begin], &ev.qs[xb.src_begin], N, nd, xb.nsrc(),
            &ev.lp[std::size_t(b) * stride], scratch.data());
        ev.has_local[b] = 1;
      }
    }
  }
}

namespace {

// The combined coefficients of every curl_grad_div and grad_div group of the local coefficients
// bcoef (b = Lh c) of a box of side s, one group after the other (l2p_block's `combined`).
void combined_group_coefficients(const Evaluation& ev, double s, const cplx* bcoef, double* combined) {
  const std::size_t nc = std::size_t(ev.nc);
  for (std::size_t g : ev.groups) {
    const unsigned f = ev.requested[g];
    if (f == kCurlGradDiv) {
      curl_grad_div_coefficients(ev.p, s, bcoef + g * nc, combined);
    } else {
      grad_div_coefficients(ev.p, s, bcoef + g * nc, combined);
    }
    combined += combined_per_group(f) * nc;
  }
}

}  // namespace

// L2P (Guan, §2.3: potential, field and field gradient from the local expansion): targets taken
// kL2PLanes at a time, the expansion's coefficients b = Lh c, and the combined coefficients of the
// curl_grad_div and grad_div groups (docs/theory/fmm.md, section 2), formed once per leaf.
void evaluate_leaf_locals(Evaluation& ev) {
  const auto& P = ev.plan;
  const auto& tree = ev.tree;
  const auto& boxes = ev.boxes;
  const auto& H = *P.H;
  const auto& leaves = tree.leaves();
  const int p = ev.p;
  const std::size_t nd = ev.nd, M = ev.M, stride = ev.stride, nc = std::size_t(ev.nc);
#pragma omp parallel if (leaves.size() >= kMinParallel)
  {
    std::vector<cplx> bcoef(stride);
    std::vector<double> scratch(2 * nc * kL2PLanes), combined(ev.combined_per_coef * nc);
    const double* rec = H.regular_recurrence();
#pragma omp for schedule(dynamic, 4)
    for (std::size_t i = 0; i < leaves.size(); ++i) {
      const LeafTimer timer(ev, i);
      const int b = leaves[i];
      const auto& bx = boxes[b];
      if (bx.ntgt() == 0 || !ev.has_local[b]) continue;
      const double s = tree.side(bx.level), inv_s = 1.0 / s;
      const auto c = tree.center(b);
      for (std::size_t d = 0; d < nd; ++d) local_to_b(H, p, &ev.lp[std::size_t(b) * stride + d * nc], &bcoef[d * nc]);
      combined_group_coefficients(ev, s, bcoef.data(), combined.data());
      for (std::size_t t0 = bx.tgt_begin; t0 < bx.tgt_end; t0 += kL2PLanes) {
        double ux[kL2PLanes], uy[kL2PLanes], uz[kL2PLanes];
        const int nt = scaled_offsets(P.tx, P.ty, P.tz, t0, bx.tgt_end, c, inv_s, ux, uy, uz);
        l2p_block(p, s, rec, bcoef.data(), nd, ev.requested.data(), nt, ux, uy, uz, &ev.res[t0 * result_width],
                  M * result_width, scratch.data(), combined.data());
      }
    }
  }
}

namespace {

// Direct sum of the sources of box src_box at the targets [tbeg, tbeg + tcount) (tree order), every
// density at once where all ask for the same outputs.
inline void add_direct(Evaluation& ev, const Box& src_box, std::size_t tbeg, std::size_t tcount) {
  const auto& P = ev.plan;
  const std::size_t N = ev.N, M = ev.M, nd = ev.nd;
  const PointsSoA tg{&P.tx[tbeg], &P.ty[tbeg], &P.tz[tbeg], tcount};
  const PointsSoA sr{&P.sx[src_box.src_begin], &P.sy[src_box.src_begin], &P.sz[src_box.src_begin], src_box.nsrc()};
  if (ev.uniform_flags) {
    laplace_p2p_add(sr, &ev.qs[src_box.src_begin], N, nd, tg, ev.outputs[0], &ev.res[tbeg * result_width],
                    M * result_width);
  } else {
    for (std::size_t d = 0; d < nd; ++d)
      laplace_p2p_add(sr, &ev.qs[d * N + src_box.src_begin], N, 1, tg, ev.outputs[d],
                      &ev.res[(d * M + tbeg) * result_width], M * result_width);
  }
}

// M2P of the multipole of box w at the targets of leaf bx (Guan, Theorems 2.2.2 and
// 2.3.2: the multipole with its derivatives). S: the singular harmonics up to p + 2, acoef: stride entries.
inline void w_box_to_targets(Evaluation& ev, int w, const Box& bx, cplx* S, cplx* acoef) {
  const auto& tree = ev.tree;
  const auto& H = *ev.plan.H;
  const auto& txyz = tree.sorted_targets();
  const int p = ev.p;
  const std::size_t nd = ev.nd, M = ev.M, stride = ev.stride, nc = std::size_t(ev.nc);
  const int pS = p + ((ev.any_flags & hessian) ? 2 : (ev.any_flags & gradient) ? 1 : 0);
  const double s = tree.side(ev.boxes[w].level);
  const auto c = tree.center(w);
  for (std::size_t d = 0; d < nd; ++d) multipole_to_a(H, p, &ev.mp[std::size_t(w) * stride + d * nc], &acoef[d * nc]);
  for (std::size_t t = bx.tgt_begin; t < bx.tgt_end; ++t) {
    const double inv_s = 1.0 / s;
    H.singular(pS, (txyz[3 * t] - c[0]) * inv_s, (txyz[3 * t + 1] - c[1]) * inv_s, (txyz[3 * t + 2] - c[2]) * inv_s, S);
    for (std::size_t d = 0; d < nd; ++d)
      m2p_eval(p, s, &acoef[d * nc], S, ev.outputs[d], &ev.res[(d * M + t) * result_width]);
  }
}

}  // namespace

// W and X lists: a box with few sources (W) or few targets (X) is cheaper by direct summation
// than by M2P or P2L (Cheng, Greengard & Rokhlin 1999 §4; Guan, Algorithm 1 step 3;
// docs/theory/fmm.md). The X-list boxes left to direct sums are those of the leaf and its
// ancestors with at most direct_limit targets. With export_direct the caller sums them.
void w_list_and_direct_far(Evaluation& ev) {
  const auto& tree = ev.tree;
  const auto& boxes = ev.boxes;
  const auto& leaves = tree.leaves();
  const std::size_t direct_limit = ev.plan.direct_limit;
  const bool export_direct = ev.plan.export_direct;
#pragma omp parallel if (leaves.size() >= kMinParallel)
  {
    std::vector<cplx> S(ncoef(ev.p + 2)), acoef(ev.stride);
#pragma omp for schedule(dynamic, 4)
    for (std::size_t i = 0; i < leaves.size(); ++i) {
      const LeafTimer timer(ev, i);
      const int b = leaves[i];
      const auto& bx = boxes[b];
      if (bx.ntgt() == 0) continue;
      for (int w : tree.wlist().of(b)) {
        const auto& wb = boxes[w];
        if (wb.nsrc() == 0) continue;
        if (wb.nsrc() <= direct_limit) {
          if (!export_direct) add_direct(ev, wb, bx.tgt_begin, bx.ntgt());
          continue;
        }
        w_box_to_targets(ev, w, bx, S.data(), acoef.data());
      }
      for (int a = b; a >= 0 && !export_direct; a = boxes[a].parent) {
        if (boxes[a].ntgt() > direct_limit) continue;
        for (int x : tree.xlist().of(a))
          if (boxes[x].nsrc() > 0) add_direct(ev, boxes[x], bx.tgt_begin, bx.ntgt());
      }
    }
  }
}

// U list, P2P: every leaf with itself and its adjacent leaves.
void u_list_direct(Evaluation& ev) {
  const auto& tree = ev.tree;
  const auto& boxes = ev.boxes;
  const auto& leaves = tree.leaves();
#pragma omp parallel for if (leaves.size() >= kMinParallel) schedule(dynamic, 4)
  for (std::size_t i = 0; i < leaves.size(); ++i) {
    const LeafTimer timer(ev, i);
    const int b = leaves[i];
    const auto& bx = boxes[b];
    if (bx.ntgt() == 0) continue;
    for (int u : tree.ulist().of(b))
      if (boxes[u].nsrc() > 0) add_direct(ev, boxes[u], bx.tgt_begin, bx.ntgt());
  }
}

namespace {

// Every column of the group's rows enters one sum at most with weight +-1 (laplace_fmm.hpp), so the
// L2P part, written into one column per sum (l2p_block), is counted once.
void fold_curl_grad_div(double* a, double* b, double* c) noexcept {
  const double folded[6] = {c[col_gy] - b[col_gz],
                            a[col_gz] - c[col_gx],
                            b[col_gx] - a[col_gy],
                            a[col_hxx] + b[col_hxy] + c[col_hxz],
                            a[col_hxy] + b[col_hyy] + c[col_hyz],
                            a[col_hxz] + b[col_hyz] + c[col_hzz]};
  std::fill_n(a, result_width, 0.0);
  std::fill_n(b, result_width, 0.0);
  std::fill_n(c, result_width, 0.0);
  std::copy_n(folded, 6, a + 1);
}

// The same for grad div alone: the Hessian columns of the three rows replaced by grad div in the
// first row's columns 4..6; potentials and gradients stay.
void fold_grad_div(double* a, double* b, double* c) noexcept {
  const double folded[3] = {a[col_hxx] + b[col_hxy] + c[col_hxz], a[col_hxy] + b[col_hyy] + c[col_hyz],
                            a[col_hxz] + b[col_hyz] + c[col_hzz]};
  for (double* r : {a, b, c}) std::fill(r + col_hxx, r + result_width, 0.0);
  std::copy_n(folded, 3, a + col_hxx);
}

}  // namespace

void fold_combined_groups(Evaluation& ev) {
  const std::size_t M = ev.M;
  for (std::size_t d : ev.groups) {
    const auto fold = ev.requested[d] == kCurlGradDiv ? fold_curl_grad_div : fold_grad_div;
    double* r0 = &ev.res[d * M * result_width];
    double* r1 = r0 + M * result_width;
    double* r2 = r1 + M * result_width;
#pragma omp parallel for if (M >= 4096) schedule(static)
    for (std::size_t t = 0; t < M; ++t) fold(r0 + t * result_width, r1 + t * result_width, r2 + t * result_width);
  }
}

void unsort_results(const Evaluation& ev, std::span<double> results) {
  const std::size_t M = ev.M, nd = ev.nd;
  const auto& res = ev.res;
  const auto& tperm = ev.tree.target_order();
#pragma omp parallel for if (M >= 4096) schedule(static)
  for (std::size_t t = 0; t < M; ++t)
    for (std::size_t d = 0; d < nd; ++d)
      std::copy_n(&res[(d * M + t) * result_width], result_width, &results[(d * M + tperm[t]) * result_width]);
}

std::vector<double> target_costs(const Evaluation& ev) {
  std::vector<double> costs(ev.M, 0.0);
  const auto& leaves = ev.tree.leaves();
  const auto& tperm = ev.tree.target_order();
  for (std::size_t i = 0; i < leaves.size(); ++i) {
    const auto& bx = ev.boxes[leaves[i]];
    if (bx.ntgt() == 0) continue;
    const double share = ev.leaf_seconds[i] / static_cast<double>(bx.ntgt());
    for (std::size_t t = bx.tgt_begin; t < bx.tgt_end; ++t) costs[tperm[t]] = share;
  }
  return costs;
}

}  // namespace rpyfmm::fmm::detail
