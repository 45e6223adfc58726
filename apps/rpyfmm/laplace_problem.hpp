// rpyfmm CLI — the input of `rpyfmm laplace`, read and validated: the serial command and its run
// across MPI ranks (laplace_across_ranks.hpp) read the same files the same way.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "rpyfmm/core/error.hpp"

namespace rpyfmm::cli {

/// Sources and targets as flat 3N and 3M (targets empty: at the sources), charges nd x N.
struct LaplaceProblem {
  std::vector<double> sources, targets, charges;
  std::size_t n = 0, m = 0, nd = 1;
  bool charges_2d = false;  // Q given as (nd, N): output (nd, M, 10)
};

/// How --charges of `shape` hold the densities for n sources: (n,) or (n,1) one density, output
/// (M,10); (nd,n) nd densities, output (nd,M,10). Throws rpyfmm::Error naming the charges for any
/// other shape.
struct ChargesLayout {
  std::size_t nd = 1;
  bool two_d = false;
};
ChargesLayout charges_layout(const std::vector<std::size_t>& shape, std::size_t n);
/// The charges' check of its values: the message for a non-finite entry at flat index `index`.
Error nonfinite_charge(std::size_t index, bool nan, const ChargesLayout& layout, std::size_t n);

/// Reads --sources, --targets (empty: none) and --charges ((N,) or (nd,N)). Throws rpyfmm::Error
/// naming the file for unreadable, malformed or mismatched input.
LaplaceProblem read_laplace_problem(const std::string& sources, const std::string& targets, const std::string& charges);

/// The shape of the output: (M,10), or (nd,M,10) when the charges were given as (nd,N).
std::vector<std::size_t> laplace_output_shape(const LaplaceProblem& p);

}  // namespace rpyfmm::cli
