// Scaling benchmark of free-draining Brownian dynamics across ranks (DistributedBd,
// rpyfmm/mpi/brownian_dynamics.hpp, docs/mpi.md "Brownian dynamics across ranks"): WCA spheres of
// radius 0.5 at volume fraction 0.15 in a periodic box (the setup of Tran et al. (2015), Tables
// 1-3, with WCA pairs), run under mpiexec by bench_mpi_ranks (bench/mpi/CMakeLists.txt) for
// bench/run.py's group "mpi".
//
// usage: bench_mpi_bd --n N [--scaling strong|weak] [--reps 3] [--steps 20]
//   (strong = N in all, weak = N per rank). The particles start on a cubic lattice (one per cell,
//   jittered by 0.05 cells, drawn from the global index) and run 20 steps before the timings.
// Prints one JSON line (rank 0): "plan_s" = the first step (partition, halo, lists and the step),
// "eval_s" = the median over reps of the time per step of `steps` steps, each the slowest rank's;
// "eval_comm_s" = the slowest rank's halo refresh per step, "essential_max" = the largest part (own
// + halo particles) of a rank, "rebuilds" per 100 steps; on one rank also "serial_s", the time per
// step of bd::Integrator with the free-draining operator on the same system (the ratio of the two
// is this layer's overhead on one rank).
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <numbers>
#include <random>
#include <vector>

#include "bench_mpi_common.hpp"
#include "rpyfmm/bd/integrator.hpp"
#include "rpyfmm/mpi/brownian_dynamics.hpp"
#include "rpyfmm/rpy/free_draining.hpp"

namespace {

constexpr double kRadius = 0.5, kVolumeFraction = 0.15;

struct System {
  double box = 0.0;
  std::vector<double> x;
  std::vector<std::uint32_t> types;
};

// Particles [first, first + count) of `total` on a cubic lattice filling the box.
System lattice_share(std::uint64_t total, std::uint64_t first, std::uint64_t count) {
  System s;
  s.box = std::cbrt(static_cast<double>(total) * 4.0 / 3.0 * std::numbers::pi * std::pow(kRadius, 3) / kVolumeFraction);
  const auto k = static_cast<std::uint64_t>(std::ceil(std::cbrt(static_cast<double>(total))));
  const double h = s.box / static_cast<double>(k);
  for (std::uint64_t i = first; i < first + count; ++i) {
    std::mt19937_64 g(i);
    std::uniform_real_distribution<double> jitter(-0.05 * h, 0.05 * h);
    const std::uint64_t cell[3] = {i % k, (i / k) % k, i / (k * k)};
    for (const std::uint64_t c : cell) s.x.push_back((static_cast<double>(c) + 0.5) * h + jitter(g));
    s.types.push_back(0);
  }
  return s;
}

rpyfmm::bd::ForceField wca() {
  rpyfmm::bd::ForceField forces({rpyfmm::bd::ParticleType{.name = "A", .radius = kRadius}});
  forces.set_pair(0, 0, {.kind = rpyfmm::bd::PairKind::wca});
  return forces;
}

rpyfmm::mpi::DistributedBdOptions options() {
  rpyfmm::mpi::DistributedBdOptions o;
  o.integrator.dt = 1e-3;
  o.integrator.kT = 1.0;
  o.integrator.seed = 3;
  return o;
}

// Seconds per step of the serial engine on the whole system (median of reps runs of `steps` steps).
double serial_seconds_per_step(const System& s, int reps, int steps) {
  const auto o = options();
  const rpyfmm::rpy::Geometry box = rpyfmm::rpy::Geometry::periodic(s.box);
  rpyfmm::bd::Integrator bd(std::make_unique<rpyfmm::rpy::FreeDrainingMobility>(box, o.viscosity), wca(), o.integrator,
                            s.x, s.types, o.neighbours);
  bd.run(20);
  return bench_mpi::median_seconds(reps, [&] { bd.run(static_cast<std::uint64_t>(steps)); }) / steps;
}

}  // namespace

int main(int argc, char** argv) {
  const auto [rank, ranks] = bench_mpi::start(&argc, &argv);
  const bench_mpi::Args a = bench_mpi::parse(argc, argv);
  int steps = 20;
  for (int i = 1; i + 1 < argc; i += 2)
    if (std::string(argv[i]) == "--steps") steps = std::atoi(argv[i + 1]);
  const auto p = static_cast<std::uint64_t>(ranks), r = static_cast<std::uint64_t>(rank);
  const std::uint64_t total =
      a.scaling == "weak" ? static_cast<std::uint64_t>(a.n) * p : static_cast<std::uint64_t>(a.n);
  const std::uint64_t first = r * (total / p) + std::min(r, total % p);
  const System s = lattice_share(total, first, total / p + (r < total % p ? 1 : 0));

  rpyfmm::mpi::DistributedBd bd(MPI_COMM_WORLD, wca(), rpyfmm::rpy::Geometry::periodic(s.box), options(),
                                {s.x, s.types, {}});
  const double plan_s = bench_mpi::median_seconds(1, [&] { bd.step(); });
  bd.run(19);
  const std::uint64_t rebuilds_before = bd.stats().rebuilds;
  const double halo_before = bd.stats().seconds.at("halo");
  const double eval_s = bench_mpi::median_seconds(a.reps, [&] { bd.run(static_cast<std::uint64_t>(steps)); }) / steps;
  const double timed_steps = static_cast<double>(a.reps) * steps;
  const double comm_s = bench_mpi::max_over_ranks((bd.stats().seconds.at("halo") - halo_before) / timed_steps);
  const double part = bench_mpi::max_over_ranks(static_cast<double>(bd.local_size() + bd.stats().halo_size));
  const double rebuilds = 100.0 * static_cast<double>(bd.stats().rebuilds - rebuilds_before) / timed_steps;
  const double serial_s = ranks == 1 ? serial_seconds_per_step(s, a.reps, steps) : 0.0;
  if (rank == 0) {
    std::printf(
        "{\"method\":\"bd\",\"scaling\":\"%s\",\"ranks\":%d,\"N\":%llu,\"plan_s\":%.6g,\"eval_s\":%.6g,"
        "\"eval_comm_s\":%.6g,\"essential_max\":%.0f,\"rebuilds\":%.3g",
        a.scaling.c_str(), ranks, static_cast<unsigned long long>(total), plan_s, eval_s, comm_s, part, rebuilds);
    if (ranks == 1) std::printf(",\"serial_s\":%.6g", serial_s);
    std::printf("}\n");
  }
  MPI_Finalize();
  return 0;
}
