// rpyfmm — the near fields of an owner's serial FMM planned with FmmOptions::near_field = false
// (DistributedFmmOptions, docs/mpi.md "Distributed FmmRpy"): which serial FMM holds which near
// pairs, which sources are equivalent nodes, and the near pairs with nodes summed as Laplace pairs.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "fmm_plan.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"

namespace rpyfmm::mpi::detail {

/// The near field of one serial FMM of a plan: its source j is the plan's essential source
/// offset + j; its targets are the owned targets. same_points: its sources are its targets
/// (the serial FMM's own mode, at the owned sources with nothing received).
struct NearPiece {
  const fmm::NearField* near = nullptr;
  std::size_t offset = 0;
  bool same_points = false;
};

/// The near fields of the serial FMMs that run on this rank: one, or the owned sources' and the
/// received sources' of the split FMM (overlap_exchange), in that order; none where no serial FMM
/// runs. Every owned target lies in one leaf of each.
[[nodiscard]] std::vector<NearPiece> near_pieces(const Plan& plan);

/// Per essential source (owned, then per rank its halo particles and its cells' nodes): 1 for an
/// equivalent node, 0 for a particle.
[[nodiscard]] std::vector<std::uint8_t> node_sources(const Plan& plan);

/// Adds to owned_results (nd x owned targets x 10, the serial FMM's layout and flags) the Laplace
/// sums of the near pairs of `piece` (its exported W/X leaf pairs included, where the serial FMM
/// exports them) whose source is an equivalent node: potential, gradient and
/// Hessian by the serial P2P kernel, folded as `outputs` ask (fmm::grad_div, fmm::curl_grad_div).
/// q: nd rows of `width` charges of the piece's sources. Serial, in the order of the piece's pairs.
void add_node_near_field(const Plan& plan, const NearPiece& piece, std::span<const double> q, std::size_t width,
                         std::size_t nd, std::span<const unsigned> outputs, std::span<double> owned_results);

}  // namespace rpyfmm::mpi::detail
