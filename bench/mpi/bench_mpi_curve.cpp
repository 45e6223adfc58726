// The partition's curve in DistributedLaplaceFmm: Morton against Hilbert order (SfcCurve,
// rpyfmm/mpi/partition.hpp; docs/mpi.md "Space-filling-curve partition"), on the same input and
// ranks, run under mpiexec by the launcher bench_mpi_ranks (bench/mpi/CMakeLists.txt).
//
// usage: bench_mpi_curve --n N --eps E [--points uniform|clustered] [--reps 3]
//   N sources in all (strong scaling), zero-mean charges, every rank drawing its contiguous share of
//   the global sequence (bench_mpi_common.hpp). clustered: the sources whose third coordinate has
//   a fractional part of 1e6 x below 1/2 (about half, drawn independently of the others) are moved
//   into one of 8 cubes of side 0.02 at fixed places in the unit cube (by their second coordinate),
//   a density contrast of about 8000; the input still depends on N only.
// Prints one JSON line per curve (rank 0): the halo particles received by all ranks together and
// by the largest receiver, the equivalent nodes received by all ranks, the largest essential set
// (own + halo + nodes, DistributedLaplaceFmm::essential_size), the regions' neighbours, the bytes of
// the plan and of one evaluate received by all ranks, the plan's time and the median over reps of
// one evaluate (one density, potential and gradient; the slowest rank's, after a barrier). The two
// curves' evaluations alternate rep by rep, so that the machine's load falls on both alike.
#include <mpi.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "bench_mpi_common.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"
#include "rpyfmm/mpi/laplace_fmm.hpp"

namespace {

using bench_mpi::max_over_ranks;
using bench_mpi::sum_over_ranks;
using rpyfmm::mpi::SfcCurve;

// Moves about half of the sources into 8 small cubes (the usage above).
void cluster(std::vector<double>& x) {
  constexpr int kClusters = 8;
  constexpr double kSide = 0.02;
  std::array<std::array<double, 3>, kClusters> centres{};
  std::mt19937_64 rng(2026);
  std::uniform_real_distribution<double> u(0.1, 0.9);
  for (auto& c : centres) {
    for (double& v : c) v = u(rng);
  }
  for (std::size_t i = 0; i < x.size(); i += 3) {
    double whole = 0.0;
    if (std::modf(x[i + 2] * 1e6, &whole) >= 0.5) continue;
    const auto k = static_cast<std::size_t>(x[i + 1] * kClusters) % kClusters;
    for (std::size_t d = 0; d < 3; ++d) x[i + d] = centres[k][d] + kSide * (x[i + d] - 0.5);
  }
}

std::string points_of(int argc, char** argv) {
  for (int i = 1; i + 1 < argc; ++i) {
    if (std::string(argv[i]) == "--points") return argv[i + 1];
  }
  return "uniform";
}

// One curve's plan, and its evaluate times.
struct Run {
  SfcCurve curve;
  rpyfmm::mpi::DistributedLaplaceFmm fmm;
  double plan_s = 0.0;
  std::vector<double> eval_times;
};

void print(const Run& r, const bench_mpi::Share& share, int ranks, double eps, const std::string& points, int rank) {
  const rpyfmm::mpi::FmmCommunication& t = r.fmm.communication();
  const auto halo = static_cast<double>(t.halo_received);
  const double halo_sum = sum_over_ranks(halo), halo_max = max_over_ranks(halo);
  const double nodes = sum_over_ranks(static_cast<double>(t.nodes_received));
  const double essential = max_over_ranks(static_cast<double>(r.fmm.essential_size()));
  const double owned = max_over_ranks(static_cast<double>(r.fmm.owned_size()));
  const double neighbours = max_over_ranks(static_cast<double>(t.region_neighbours));
  const double plan_bytes = sum_over_ranks(static_cast<double>(t.plan_bytes_received));
  const double eval_bytes = sum_over_ranks(static_cast<double>(t.evaluate_bytes_received));
  if (rank != 0) return;
  std::printf("{\"method\":\"fmm_curve\",\"curve\":\"%s\",\"points\":\"%s\",\"ranks\":%d,\"N\":%llu,\"eps\":%g",
              r.curve == SfcCurve::hilbert ? "hilbert" : "morton", points.c_str(), ranks,
              static_cast<unsigned long long>(share.total), eps);
  std::printf(",\"owned_max\":%.0f,\"halo\":%.0f,\"halo_max\":%.0f,\"nodes\":%.0f,\"essential_max\":%.0f", owned,
              halo_sum, halo_max, nodes, essential);
  std::printf(",\"region_neighbours_max\":%.0f,\"plan_MB\":%.6g,\"eval_MB\":%.6g,\"plan_s\":%.6g,\"eval_s\":%.6g}\n",
              neighbours, plan_bytes / 1e6, eval_bytes / 1e6, r.plan_s, bench_mpi::median(r.eval_times));
}

}  // namespace

int main(int argc, char** argv) {
  const auto [rank, ranks] = bench_mpi::start(&argc, &argv);
  const bench_mpi::Args a = bench_mpi::parse(argc, argv);
  bench_mpi::Share share = bench_mpi::make_share(a, rank, ranks, 1);
  const std::string points = points_of(argc, argv);
  if (points == "clustered") cluster(share.x);

  std::vector<Run> runs;
  for (SfcCurve curve : {SfcCurve::morton, SfcCurve::hilbert}) {
    rpyfmm::mpi::DistributedFmmOptions options;
    options.fmm.tolerance = a.eps;
    options.curve = curve;
    runs.push_back(Run{curve, rpyfmm::mpi::DistributedLaplaceFmm(MPI_COMM_WORLD, options), 0.0, {}});
    runs.back().plan_s = bench_mpi::median_seconds(1, [&] { runs.back().fmm.set_points(share.x); });
  }
  std::vector<double> results(share.x.size() / 3 * rpyfmm::fmm::result_width);
  for (int r = 0; r < a.reps; ++r) {
    for (Run& run : runs) {
      run.eval_times.push_back(bench_mpi::median_seconds(
          1, [&] { run.fmm.evaluate(share.q, 1, rpyfmm::fmm::potential | rpyfmm::fmm::gradient, results); }));
    }
  }
  for (const Run& run : runs) print(run, share, ranks, a.eps, points, rank);
  MPI_Finalize();
  return 0;
}
