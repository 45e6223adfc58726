// What the MPI benchmarks share (bench/mpi): their arguments, each rank's contiguous share of one
// global sequence of uniform sources, and reductions over the ranks.
#pragma once

#include <mpi.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <random>
#include <string>
#include <utility>
#include <vector>

namespace bench_mpi {

/// MPI_Init; this process's rank and the number of ranks.
struct World {
  int rank = 0, ranks = 1;
};
inline World start(int* argc, char*** argv) {
  MPI_Init(argc, argv);
  World w;
  MPI_Comm_rank(MPI_COMM_WORLD, &w.rank);
  MPI_Comm_size(MPI_COMM_WORLD, &w.ranks);
  return w;
}

struct Args {
  double n = 1e5, eps = 1e-6;
  std::string scaling = "strong";  // strong: n in all; weak: n per rank
  int reps = 3;
};

inline Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string k = argv[i], v = argv[i + 1];
    if (k == "--n") a.n = std::atof(v.c_str());
    if (k == "--eps") a.eps = std::atof(v.c_str());
    if (k == "--scaling") a.scaling = v;
    if (k == "--reps") a.reps = std::atoi(v.c_str());
  }
  return a;
}

/// This rank's share of the global sequence: positions in the unit cube and one value in [-0.5, 0.5)
/// per source (a charge, or a force component). Each source is drawn from its global index, so the
/// input does not depend on P beyond its size.
struct Share {
  std::uint64_t total = 0;
  std::vector<double> x, q;
};

inline Share make_share(const Args& a, int rank, int ranks, int values_per_source) {
  const auto p = static_cast<std::uint64_t>(ranks), r = static_cast<std::uint64_t>(rank);
  Share s;
  s.total = a.scaling == "weak" ? static_cast<std::uint64_t>(a.n) * p : static_cast<std::uint64_t>(a.n);
  const std::uint64_t count = s.total / p + (r < s.total % p ? 1 : 0);
  const std::uint64_t first = r * (s.total / p) + std::min(r, s.total % p);
  s.x.resize(3 * count);
  s.q.resize(static_cast<std::size_t>(values_per_source) * count);
  for (std::uint64_t i = 0; i < count; ++i) {
    std::mt19937_64 g(first + i);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (int k = 0; k < 3; ++k) s.x[3 * i + static_cast<std::uint64_t>(k)] = u(g);
    for (int k = 0; k < values_per_source; ++k)
      s.q[static_cast<std::uint64_t>(values_per_source) * i + static_cast<std::uint64_t>(k)] = u(g) - 0.5;
  }
  return s;
}

inline double reduce(double v, MPI_Op op) {
  double out = 0.0;
  MPI_Allreduce(&v, &out, 1, MPI_DOUBLE, op, MPI_COMM_WORLD);
  return out;
}
inline double max_over_ranks(double v) {
  return reduce(v, MPI_MAX);
}
inline double sum_over_ranks(double v) {
  return reduce(v, MPI_SUM);
}

/// The median of `values` (not empty).
inline double median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  return values[values.size() / 2];
}

/// The median of reps timings of `body`, each the slowest rank's after a barrier.
template <class Body>
double median_seconds(int reps, Body&& body) {
  std::vector<double> times;
  for (int r = 0; r < reps; ++r) {
    MPI_Barrier(MPI_COMM_WORLD);
    const double start = MPI_Wtime();
    body();
    times.push_back(max_over_ranks(MPI_Wtime() - start));
  }
  return median(std::move(times));
}

}  // namespace bench_mpi
