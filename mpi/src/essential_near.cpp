// rpyfmm — the near fields of an owner's serial FMM without its near field (essential_near.hpp).
#include "essential_near.hpp"

#include <algorithm>

#include "rpyfmm/fmm/direct.hpp"

namespace rpyfmm::mpi::detail {
namespace {

// The Hessian column (fmm::Column) of d_c d_m.
constexpr std::size_t kHessian[3][3] = {{fmm::col_hxx, fmm::col_hxy, fmm::col_hxz},
                                        {fmm::col_hxy, fmm::col_hyy, fmm::col_hyz},
                                        {fmm::col_hxz, fmm::col_hyz, fmm::col_hzz}};

// Adds the columns that plain flags (potential | gradient | hessian) ask for.
void add_plain(unsigned flags, const double* from, double* to) {
  if (flags & fmm::potential) to[fmm::col_pot] += from[fmm::col_pot];
  if (flags & fmm::gradient)
    for (std::size_t c = fmm::col_gx; c <= fmm::col_gz; ++c) to[c] += from[c];
  if (flags & fmm::hessian)
    for (std::size_t c = fmm::col_hxx; c <= fmm::col_hyz; ++c) to[c] += from[c];
}

// Adds one group of three densities (rows g[0..2] of full results at a target) to the rows
// to[0..2] as its flags ask: curl_grad_div, curl Phi in the first row's columns 1..3; grad_div,
// each density's own potential and gradient; both, grad div Phi in the first row's columns 4..6
// (fmm/include/rpyfmm/fmm/laplace_fmm.hpp).
void add_group(const unsigned* flags, const double* const g[3], double* const to[3]) {
  if (flags[0] == fmm::curl_grad_div) {
    to[0][fmm::col_gx] += g[2][fmm::col_gy] - g[1][fmm::col_gz];
    to[0][fmm::col_gy] += g[0][fmm::col_gz] - g[2][fmm::col_gx];
    to[0][fmm::col_gz] += g[1][fmm::col_gx] - g[0][fmm::col_gy];
  } else {
    for (std::size_t m = 0; m < 3; ++m) add_plain(flags[m] & (fmm::potential | fmm::gradient), g[m], to[m]);
  }
  for (std::size_t c = 0; c < 3; ++c)
    to[0][fmm::col_hxx + c] += g[0][kHessian[c][0]] + g[1][kHessian[c][1]] + g[2][kHessian[c][2]];
}

// Adds the full results `full` (nd x t x 10) at the targets `targets` to `results` (nd x mt x 10).
void fold(const std::vector<double>& full, std::size_t nd, std::span<const std::size_t> targets,
          std::span<const unsigned> outputs, std::span<double> results, std::size_t mt) {
  const std::size_t t = targets.size();
  const auto from = [&](std::size_t d, std::size_t q) { return full.data() + (d * t + q) * fmm::result_width; };
  const auto to = [&](std::size_t d, std::size_t i) { return results.data() + (d * mt + i) * fmm::result_width; };
  for (std::size_t d = 0; d < nd;) {
    const bool group = outputs[d] == fmm::curl_grad_div || (outputs[d] & fmm::grad_div) != 0;
    for (std::size_t q = 0; q < t; ++q) {
      if (group) {
        const double* const g[3] = {from(d, q), from(d + 1, q), from(d + 2, q)};
        double* const rows[3] = {to(d, targets[q]), to(d + 1, targets[q]), to(d + 2, targets[q])};
        add_group(outputs.data() + d, g, rows);
      } else {
        add_plain(outputs[d], from(d, q), to(d, targets[q]));
      }
    }
    d += group ? 3 : 1;
  }
}

// Points gathered into structure-of-arrays form.
struct Gathered {
  std::vector<double> x, y, z;
  void clear() {
    x.clear();
    y.clear();
    z.clear();
  }
  void push(const double* p) {
    x.push_back(p[0]);
    y.push_back(p[1]);
    z.push_back(p[2]);
  }
  [[nodiscard]] fmm::PointsSoA view() const { return {x.data(), y.data(), z.data(), x.size()}; }
};

}  // namespace

std::vector<NearPiece> near_pieces(const Plan& plan) {
  const std::size_t m = plan.owned_x.size() / 3;
  std::vector<NearPiece> pieces;
  if (!plan.split) {
    if (plan.sources > 0) pieces.push_back({&plan.fmm.near_field(), 0, !plan.target_partition && plan.sources == m});
    return pieces;
  }
  if (plan.own_runs) pieces.push_back({&plan.own_fmm.near_field(), 0, !plan.target_partition});
  if (plan.received_runs) pieces.push_back({&plan.received_fmm.near_field(), m, false});
  return pieces;
}

std::vector<std::uint8_t> node_sources(const Plan& plan) {
  std::vector<std::uint8_t> node(plan.owned_x.size() / 3, 0);
  for (std::size_t r = 0; r < plan.recv_halo.size(); ++r) {
    node.insert(node.end(), plan.recv_halo[r], 0);
    node.insert(node.end(), plan.recv_nodes[r], 1);
  }
  return node;
}

void add_node_near_field(const Plan& plan, const NearPiece& piece, std::span<const double> q, std::size_t width,
                         std::size_t nd, std::span<const unsigned> outputs, std::span<double> owned_results) {
  const std::size_t mt = plan.targets().owned_size();
  const std::vector<double>& tx = plan.target_x();
  Gathered sources, targets;
  std::vector<std::size_t> nodes;
  std::vector<double> charges, full;
  for (const auto& [target_leaf, source_leaf] : piece.near->pairs) {
    nodes.clear();
    for (std::size_t j : piece.near->sources(source_leaf))
      if (plan.node[piece.offset + j] != 0) nodes.push_back(j);
    const std::span<const std::size_t> at = piece.near->targets(target_leaf);
    if (nodes.empty() || at.empty()) continue;
    const std::size_t k = nodes.size();
    sources.clear();
    charges.resize(nd * k);
    for (std::size_t s = 0; s < k; ++s) {
      sources.push(plan.essential_x.data() + 3 * (piece.offset + nodes[s]));
      for (std::size_t d = 0; d < nd; ++d) charges[d * k + s] = q[d * width + nodes[s]];
    }
    targets.clear();
    for (std::size_t i : at) targets.push(tx.data() + 3 * i);
    full.assign(nd * at.size() * fmm::result_width, 0.0);
    fmm::laplace_p2p_add(sources.view(), charges.data(), k, nd, targets.view(), fmm::all_outputs, full.data(),
                         at.size() * fmm::result_width);
    fold(full, nd, at, outputs, owned_results, mt);
  }
}

}  // namespace rpyfmm::mpi::detail
