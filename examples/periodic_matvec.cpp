// rpyfmm as a matvec library for a periodic suspension: U = M F and Brownian displacements
// w = M^{1/2} z by Positively Split Ewald, on the CPU and, where a GPU is usable, on the GPU,
// through the same interface (rpyfmm::rpy::MobilityOperator). Prints, per operator, the time
// of set_positions, of one product and of one sample, the hindered settling ratio <U_z> / U_0
// of equal forces (U_0 = F / (6 pi eta a)), and the GPU's difference from the CPU.
//
//   example_periodic_matvec [N]      (default 4000 spheres of radius 1 at volume fraction 0.05)
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <numbers>
#include <random>
#include <vector>

#include "rpyfmm/rpy/mobility.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/pse/pse_rpy_cuda.hpp"
#include "rpyfmm/rpy/random.hpp"

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

double relative_difference(const std::vector<double>& a, const std::vector<double>& b) {
  double num = 0.0, den = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    num += (a[i] - b[i]) * (a[i] - b[i]);
    den += b[i] * b[i];
  }
  return std::sqrt(num / den);
}

}  // namespace

int main(int argc, char** argv) {
  using namespace rpyfmm::rpy;
  const long requested = argc > 1 ? std::atol(argv[1]) : 4000;
  if (requested < 1) {
    std::fprintf(stderr, "example_periodic_matvec: N must be a positive integer\n");
    return 2;
  }
  const auto n = static_cast<std::size_t>(requested);
  const double a = 1.0, eta = 1.0, phi = 0.05;
  const double L = std::cbrt(static_cast<double>(n) * 4.0 / 3.0 * std::numbers::pi * a * a * a / phi);

  // Uniformly random centres (overlaps are allowed: the RPY tensor is regularized for them),
  // unit forces along -z, and a standard normal vector z for the sample.
  std::mt19937_64 gen(42);
  std::uniform_real_distribution<double> uniform(0.0, L);
  std::vector<double> x(3 * n), f(3 * n, 0.0), z(3 * n);
  for (double& v : x) v = uniform(gen);
  for (std::size_t i = 0; i < n; ++i) f[3 * i + 2] = -1.0;
  fill_normal(z, /*seed=*/7, /*step=*/0);

  pse::PseOptions options;
  options.tolerance = 1e-4;
  std::vector<std::unique_ptr<MobilityOperator>> operators;
  operators.push_back(std::make_unique<pse::PseRpy>(Geometry::periodic(L), eta, options));
  if (pse::PseRpyCuda::device_available()) {
    operators.push_back(std::make_unique<pse::PseRpyCuda>(Geometry::periodic(L), eta, options));
  } else {
    std::printf("(no usable CUDA device, or a build without CUDA: CPU only)\n");
  }

  std::printf("%zu spheres, box %.2f, tolerance %.0e\n", n, L, options.tolerance);
  std::printf("%-10s %16s %12s %12s %14s  %s\n", "operator", "set_positions s", "M F s", "M^1/2 z s", "<U_z> / U_0",
              "relative difference from the CPU");
  const double u0 = 1.0 / (6.0 * std::numbers::pi * eta * a);
  std::vector<double> u_cpu, w_cpu;
  for (const auto& op : operators) {
    std::vector<double> u(3 * n), w(3 * n);
    auto t0 = std::chrono::steady_clock::now();
    op->set_positions(x, a);
    const double t_positions = seconds_since(t0);
    t0 = std::chrono::steady_clock::now();
    op->apply(f, u);
    const double t_product = seconds_since(t0);
    t0 = std::chrono::steady_clock::now();
    op->apply_sqrt(z, w);  // the split sampler: M_r^{1/2} by Lanczos, the wave part by the FFTs
    const double t_sample = seconds_since(t0);
    double mean_uz = 0.0;
    for (std::size_t i = 0; i < n; ++i) mean_uz += u[3 * i + 2];
    mean_uz /= static_cast<double>(n);
    const bool first = u_cpu.empty();
    if (first) {
      u_cpu = u;
      w_cpu = w;
    }
    std::printf("%-10s %16.4f %12.4f %12.4f %14.4f", op->name().c_str(), t_positions, t_product, t_sample,
                -mean_uz / u0);
    if (first) {
      std::printf("  -\n");
    } else {
      std::printf("  M F %.1e, M^1/2 z %.1e\n", relative_difference(u, u_cpu), relative_difference(w, w_cpu));
    }
  }
  // Centres placed independently carry no pair correlations, so the pair sums average out (the
  // periodic Green's function integrates to zero over the box: no net flow) and the ratio is
  // close to the single sphere's periodic self-mobility 1 - 2.837297 a/L + (4 pi / 3) (a/L)^3
  // (Hasimoto). Hard spheres, whose neighbours are kept away, settle slower (Batchelor:
  // 1 - 6.55 phi).
  const double self = 1.0 - 2.837297 * a / L + 4.0 * std::numbers::pi / 3.0 * std::pow(a / L, 3);
  std::printf("single sphere in this box: %.4f\n", self);
  return 0;
}
