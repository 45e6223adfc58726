// rpyfmm CLI — the input of `rpyfmm laplace`, read and validated: the serial command and its run
// across MPI ranks (laplace_across_ranks.hpp) read the same files the same way.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace rpyfmm::cli {

/// Sources and targets as flat 3N and 3M (targets empty: at the sources), charges nd x N.
struct LaplaceProblem {
  std::vector<double> sources, targets, charges;
  std::size_t n = 0, m = 0, nd = 1;
  bool charges_2d = false;  // Q given as (nd, N): output (nd, M, 10)
};

/// Reads --sources, --targets (empty: none) and --charges ((N,) or (nd,N)). Throws rpyfmm::Error
/// naming the file for unreadable, malformed or mismatched input.
LaplaceProblem read_laplace_problem(const std::string& sources, const std::string& targets, const std::string& charges);

/// The shape of the output: (M,10), or (nd,M,10) when the charges were given as (nd,N).
std::vector<std::size_t> laplace_output_shape(const LaplaceProblem& p);

}  // namespace rpyfmm::cli
