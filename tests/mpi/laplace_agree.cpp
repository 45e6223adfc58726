// laplace_agree A.npy B.npy BOUND — whether two outputs of `rpyfmm laplace` ((M,10) or
// (nd,M,10), columns pot, gx, gy, gz, hxx, hyy, hzz, hxy, hxz, hyz) agree to BOUND in the relative
// l2 norm of each output of each density (the potential, the gradient, the Hessian): the FMM's
// tolerance contract (rpyfmm/fmm/laplace_fmm.hpp); or two outputs of `rpyfmm mobility` ((N,3)) in
// the relative l2 norm of U, the contract of the FMM mobility, or with rotation ((N,6), columns Ux Uy
// Uz Wx Wy Wz) in that of U and that of W each; or two trajectories of `rpyfmm rigid-bd` ((frames,m,7),
// columns q_x q_y q_z w x y z) in those of the positions and of the orientations of each frame.
// Prints the differences; exits 0
// when every one is at most BOUND, 1 otherwise and 2 for unreadable or mismatched files. Used by
// tests/mpi/cli_across_ranks.cmake.
#include <cmath>
#include <cstddef>
#include <cstdlib>
#include <exception>
#include <iostream>
#include <span>
#include <string>

#include "array_io.hpp"

namespace {

struct Output {
  const char* name;
  std::size_t first, count;  // columns
};
constexpr Output kLaplaceOutputs[] = {{"potential", 0, 1}, {"gradient", 1, 3}, {"hessian", 4, 6}};
constexpr Output kMobilityOutputs[] = {{"velocity", 0, 3}};
constexpr Output kRotationOutputs[] = {{"velocity", 0, 3}, {"angular velocity", 3, 3}};
constexpr Output kTrajectoryOutputs[] = {{"positions", 0, 3}, {"orientations", 3, 4}};
constexpr std::size_t kLaplaceWidth = 10, kMobilityWidth = 3, kRotationWidth = 6, kTrajectoryWidth = 7;

// || a - b || / || b || over the rows [row0, row0 + rows) and the output's columns.
double relative_difference(const rpyfmm::cli::Array& a, const rpyfmm::cli::Array& b, std::size_t row0, std::size_t rows,
                           std::size_t width, const Output& out) {
  double diff = 0.0, norm = 0.0;
  for (std::size_t i = row0; i < row0 + rows; ++i)
    for (std::size_t c = out.first; c < out.first + out.count; ++c) {
      const double d = a.data[i * width + c] - b.data[i * width + c];
      diff += d * d;
      norm += b.data[i * width + c] * b.data[i * width + c];
    }
  return std::sqrt(diff / norm);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 4) {
    std::cerr << "usage: laplace_agree A.npy B.npy BOUND\n";
    return 2;
  }
  try {
    const rpyfmm::cli::Array a = rpyfmm::cli::read_array(argv[1]);
    const rpyfmm::cli::Array b = rpyfmm::cli::read_array(argv[2]);
    const double bound = std::stod(argv[3]);
    const std::size_t width = a.shape.empty() ? 0 : a.shape.back();
    const bool mobility = a.shape.size() == 2 && width == kMobilityWidth;
    const bool rotation = a.shape.size() == 2 && width == kRotationWidth;
    const bool trajectory = a.shape.size() == 3 && width == kTrajectoryWidth;
    if (a.shape != b.shape || a.shape.size() < 2 || (width != kLaplaceWidth && !mobility && !rotation && !trajectory)) {
      std::cerr << "laplace_agree: the files' shapes differ or are not (M,10), (nd,M,10), (N,3), (N,6) or "
                   "(frames,m,7)\n";
      return 2;
    }
    std::span<const Output> outputs(kLaplaceOutputs);
    if (mobility) outputs = kMobilityOutputs;
    if (rotation) outputs = kRotationOutputs;
    if (trajectory) outputs = kTrajectoryOutputs;
    const std::size_t rows = a.shape[a.shape.size() - 2];
    const std::size_t densities = a.data.size() / (rows * width);
    bool agree = true;
    for (std::size_t d = 0; d < densities; ++d)
      for (const Output& out : outputs) {
        const double e = relative_difference(a, b, d * rows, rows, width, out);
        std::cout << "density " << d << ' ' << out.name << ": " << e << '\n';
        agree = agree && e <= bound;  // NaN fails
      }
    return agree ? 0 : 1;
  } catch (const std::exception& e) {
    std::cerr << "laplace_agree: " << e.what() << '\n';
    return 2;
  }
}
