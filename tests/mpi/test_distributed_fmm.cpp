// rpyfmm::mpi::DistributedLaplaceFmm against the serial LaplaceFmm and the direct sum on the whole
// set, to the serial FMM's contract (docs/theory/fmm.md: the relative l2 error of each output,
// measured on its own, at most the tolerance), on uniform and clustered sets, empty ranks and more
// ranks than particles; the compression error against its rule (docs/mpi.md, "Error rule");
// results independent of how the input is distributed, repeated evaluations bit for bit, new points
// on one object, the serial FMM split to overlap the exchanges (overlap_exchange), the partition
// along the Hilbert curve (curve), separate targets partitioned by the sources' cuts
// (targets_follow_sources: accuracy, ownership aligned with the sources' key ranges), and
// collective failure.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "mpi_test_support.hpp"
#include "rpyfmm/fmm/direct.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"
#include "rpyfmm/mpi/laplace_fmm.hpp"

using rpyfmm::ErrorCode;
using rpyfmm::mpi::DistributedFmmOptions;
using rpyfmm::mpi::DistributedLaplaceFmm;
using rpyfmm::mpi::SfcCurve;
using namespace rpyfmm_mpi_test;
namespace fmm = rpyfmm::fmm;

namespace {

constexpr std::size_t W = fmm::result_width;

// N sources (3N positions) and nd charge vectors (nd x N), the same on every rank for one seed.
struct Cloud {
  std::vector<double> x, q;
  std::size_t nd = 1;
  [[nodiscard]] std::size_t size() const { return x.size() / 3; }
};

// Charges in [-1, 1] (zero mean: the relative error of a field with cancellations is the hard case).
void add_charges(Cloud& c, std::size_t nd, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  c.nd = nd;
  c.q.resize(nd * c.size());
  for (double& v : c.q) v = u(rng);
}

Cloud uniform_cloud(std::size_t n, std::size_t nd, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Cloud c;
  for (std::size_t i = 0; i < 3 * n; ++i) c.x.push_back(u(rng));
  add_charges(c, nd, rng);
  return c;
}

// `n_cluster` points in a ball of radius 3 (one pair coincident) and `n_rest` spread over a cube of
// side 1000 at a distance of 5000 (clustered_particles): the cluster falls inside one rank's share
// of the Morton order.
Cloud clustered_cloud(std::size_t n_cluster, std::size_t n_rest, std::size_t nd, std::uint64_t seed) {
  Cloud c;
  c.x = clustered_particles(n_cluster, n_rest, seed).x;
  std::mt19937_64 rng(seed + 1);
  add_charges(c, nd, rng);
  return c;
}

// This rank's share of a cloud split by `split`: positions and charges (nd x n).
struct Share {
  Partition part;
  std::vector<double> x, q;
};

Share share_of(const Cloud& c, Split split) {
  Share s;
  s.part = partition_of(c.size(), split);
  s.x = share(c.x, 3, s.part.offset, s.part.n);
  for (std::size_t d = 0; d < c.nd; ++d) {
    const auto first = c.q.begin() + static_cast<std::ptrdiff_t>(d * c.size() + s.part.offset);
    s.q.insert(s.q.end(), first, first + static_cast<std::ptrdiff_t>(s.part.n));
  }
  return s;
}

// Every rank's results (nd x n x 10) assembled into the whole set's (nd x N x 10), on every rank.
std::vector<double> gather_results(const std::vector<double>& local, std::size_t nd, std::size_t n_total, Split split) {
  const auto ranks = static_cast<std::size_t>(world_size());
  const std::vector<std::size_t> counts = split_counts(n_total, ranks, split);
  std::vector<int> cnt(ranks), dsp(ranks);
  for (std::size_t r = 0, at = 0; r < ranks; at += counts[r], ++r) {
    cnt[r] = static_cast<int>(W * counts[r]);
    dsp[r] = static_cast<int>(W * at);
  }
  const std::size_t mine = counts[static_cast<std::size_t>(world_rank())];
  std::vector<double> all(nd * n_total * W);
  for (std::size_t d = 0; d < nd; ++d) {
    MPI_Allgatherv(local.data() + d * mine * W, static_cast<int>(mine * W), MPI_DOUBLE, all.data() + d * n_total * W,
                   cnt.data(), dsp.data(), MPI_DOUBLE, MPI_COMM_WORLD);
  }
  return all;
}

// The distributed results on the whole set, gathered on every rank.
std::vector<double> distributed(DistributedLaplaceFmm& f, const Cloud& c, std::span<const unsigned> outputs,
                                Split split) {
  const Share s = share_of(c, split);
  f.set_points(s.x);
  std::vector<double> local(c.nd * s.part.n * W);
  f.evaluate(s.q, c.nd, outputs, local);
  return gather_results(local, c.nd, c.size(), split);
}

// The serial FMM and the direct sum on the whole set, at the sources or at `targets` (3M).
std::vector<double> serial_fmm(const Cloud& c, std::span<const unsigned> outputs, double tolerance,
                               std::span<const double> targets = {}) {
  fmm::LaplaceFmm f({.tolerance = tolerance});
  f.set_points(c.x, targets);
  std::vector<double> r(c.nd * f.num_targets() * W);
  f.evaluate(c.q, c.nd, outputs, r);
  return r;
}

std::vector<double> direct(const Cloud& c, std::span<const unsigned> outputs, std::span<const double> targets = {}) {
  const std::size_t m = targets.empty() ? c.size() : targets.size() / 3;
  std::vector<double> r(c.nd * m * W), one(m * W);
  for (std::size_t d = 0; d < c.nd; ++d) {
    fmm::laplace_direct(c.x, std::span<const double>(c.q).subspan(d * c.size(), c.size()), 1, targets, outputs[d], one);
    std::copy(one.begin(), one.end(), r.begin() + static_cast<std::ptrdiff_t>(d * m * W));
  }
  return r;
}

// The largest relative l2 error over densities and requested outputs (potential, gradient and
// Hessian each measured on its own, docs/theory/fmm.md).
double worst_error(const std::vector<double>& got, const std::vector<double>& ref, std::span<const unsigned> outputs,
                   std::size_t n) {
  struct Group {
    unsigned flag;
    std::size_t first, last;
  };
  const Group groups[] = {{fmm::potential, 0, 1}, {fmm::gradient, 1, 4}, {fmm::hessian, 4, 10}};
  double worst = 0.0;
  for (std::size_t d = 0; d < outputs.size(); ++d) {
    for (const Group& g : groups) {
      if ((outputs[d] & g.flag) == 0) continue;
      double num = 0.0, den = 0.0;
      for (std::size_t i = 0; i < n; ++i) {
        for (std::size_t k = g.first; k < g.last; ++k) {
          const double a = got[(d * n + i) * W + k], b = ref[(d * n + i) * W + k];
          num += (a - b) * (a - b);
          den += b * b;
        }
      }
      worst = std::max(worst, std::sqrt(num / den));
    }
  }
  return worst;
}

// The sum over ranks of a count.
std::uint64_t total(std::uint64_t mine) {
  std::uint64_t sum = 0;
  MPI_Allreduce(&mine, &sum, 1, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD);
  return sum;
}

DistributedFmmOptions with_tolerance(double tolerance, bool overlap_exchange = false,
                                     SfcCurve curve = SfcCurve::morton) {
  DistributedFmmOptions o;
  o.fmm.tolerance = tolerance;
  o.overlap_exchange = overlap_exchange;
  o.curve = curve;
  return o;
}

const unsigned kTwoOutputs[] = {fmm::potential | fmm::gradient, fmm::all_outputs};

// The distributed FMM within `tolerance` of the direct sum and of the serial FMM, and the same bits
// when the input is all on the last rank (the partition and so the plan depend on the global set
// only). Returns the compressed cells received, summed over the ranks.
std::uint64_t expect_contract(const Cloud& c, const std::vector<double>& exact, double tolerance,
                              std::span<const unsigned> outputs, bool overlap_exchange = false,
                              SfcCurve curve = SfcCurve::morton) {
  const std::vector<double> serial = serial_fmm(c, outputs, tolerance);
  DistributedLaplaceFmm f(MPI_COMM_WORLD, with_tolerance(tolerance, overlap_exchange, curve));
  const std::vector<double> even = distributed(f, c, outputs, Split::even);
  EXPECT_LE(worst_error(even, exact, outputs, c.size()), tolerance) << "against the direct sum, eps " << tolerance;
  EXPECT_LE(worst_error(even, serial, outputs, c.size()), tolerance) << "against the serial FMM, eps " << tolerance;
  const std::uint64_t cells = total(f.communication().cells_received);
  EXPECT_EQ(bitwise_mismatches(distributed(f, c, outputs, Split::last_only), even), 0u) << "input on the last rank";
  return cells;
}

// Plans `s` and evaluates twice: the same bits both times (a failure otherwise); returns the results.
std::vector<double> planned_and_evaluated_twice(DistributedLaplaceFmm& f, const Cloud& c, const Share& s,
                                                std::span<const unsigned> outputs) {
  f.set_points(s.x);
  std::vector<double> first(c.nd * s.part.n * W), again(first.size());
  f.evaluate(s.q, c.nd, outputs, first);
  f.evaluate(s.q, c.nd, outputs, again);
  EXPECT_EQ(bitwise_mismatches(first, again), 0u) << "a repeated evaluation differs";
  return first;
}

TEST(DistributedFmm, UniformMatchesDirectAndSerial) {
  const Cloud c = uniform_cloud(3000, 2, 11);
  const std::vector<double> exact = direct(c, kTwoOutputs);
  for (double tolerance : {1e-3, 1e-6, 1e-9}) expect_contract(c, exact, tolerance, kTwoOutputs);
}

TEST(DistributedFmm, ClusterInsideOneShareIsCompressed) {
  // 1200 points in a ball of radius 3 and 4800 in a cube of side 1000: on two or more ranks the
  // cluster's cells reach the other ranks as equivalent charges.
  const Cloud c = clustered_cloud(1200, 4800, 2, 12);
  const std::vector<double> exact = direct(c, kTwoOutputs);
  for (double tolerance : {1e-3, 1e-6, 1e-9}) {
    const std::uint64_t cells = expect_contract(c, exact, tolerance, kTwoOutputs);
    if (world_size() > 1) {
      EXPECT_GT(cells, 0u) << "no cell was compressed at eps " << tolerance;
    } else {
      EXPECT_EQ(cells, 0u);
    }
  }
}

TEST(DistributedFmm, CompressionErrorBelowTheRuleAtFixedOrders) {
  // The serial FMM at 1e-12, so that the error measured is the compression's: with order p for every
  // compressed cell at a distance of at least eta h, within rho^-p (docs/mpi.md, "Error rule"), and
  // compression really used (an error well above the serial FMM's) on more than one rank.
  const Cloud c = uniform_cloud(4000, 1, 13);
  const unsigned outputs[] = {fmm::potential | fmm::gradient};
  const std::vector<double> exact = direct(c, outputs);
  for (int p : {2, 3, 4}) {
    DistributedFmmOptions o = with_tolerance(1e-12);
    o.separation = 2.0;
    o.chebyshev_order = p;
    DistributedLaplaceFmm f(MPI_COMM_WORLD, o);
    const double error = worst_error(distributed(f, c, outputs, Split::even), exact, outputs, c.size());
    const double rho = 2.0 + std::sqrt(5.0);
    EXPECT_LE(error, std::pow(rho, -p)) << "order " << p;
    if (world_size() > 1) {
      EXPECT_GT(error, 1e-10) << "order " << p << ": no compression error at all";
    }
  }
}

TEST(DistributedFmm, FarFromTheOrigin) {
  // A unit cube of sources at 2^40 on every axis, where coordinates are rounded to 2^-12, against
  // the same sources moved exactly to the origin: with node positions and cubes taken in absolute
  // coordinates the compression error grows by 15 % there (order 4); the plan works next to the
  // cloud's centre, as the serial FMM does, and the errors agree.
  Cloud far = uniform_cloud(4000, 1, 19), near;
  for (double& v : far.x) v += 0x1p40;
  near = far;
  for (double& v : near.x) v -= 0x1p40;  // exact
  const unsigned outputs[] = {fmm::potential | fmm::gradient};
  DistributedFmmOptions o = with_tolerance(1e-12);
  o.chebyshev_order = 4;
  DistributedLaplaceFmm f(MPI_COMM_WORLD, o);
  const double error_far =
      worst_error(distributed(f, far, outputs, Split::even), direct(far, outputs), outputs, far.size());
  if (world_size() > 1) {
    EXPECT_GT(total(f.communication().cells_received), 0u);
  }
  const double error_near =
      worst_error(distributed(f, near, outputs, Split::even), direct(near, outputs), outputs, near.size());
  EXPECT_LE(error_far, 1.01 * error_near + 1e-12);
}

TEST(DistributedFmm, TargetsDistributedApartFromSources) {
  // Sources: the clustered set (split evenly); targets: 600 in the far cube, 300 in a cube of side
  // 5.8 around the cluster and 10 on sources (those pairs skipped), split two other ways.
  const Cloud c = clustered_cloud(800, 2200, 2, 20);
  std::mt19937_64 rng(21);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> targets;
  for (int i = 0; i < 600; ++i) {
    for (int d = 0; d < 3; ++d) targets.push_back(5000.0 + 500.0 * u(rng));
  }
  for (int i = 0; i < 900; ++i) targets.push_back(5.0 * u(rng) / std::sqrt(3.0));
  targets.insert(targets.end(), c.x.begin(), c.x.begin() + 30);
  const std::size_t m = targets.size() / 3;
  const std::vector<double> exact = direct(c, kTwoOutputs, targets);
  const Share s = share_of(c, Split::even);
  for (double tolerance : {1e-3, 1e-6}) {
    const std::vector<double> serial = serial_fmm(c, kTwoOutputs, tolerance, targets);
    DistributedLaplaceFmm f(MPI_COMM_WORLD, with_tolerance(tolerance));
    std::vector<double> first;
    for (Split split : {Split::last_only, Split::geometric}) {
      const Partition t = partition_of(m, split);
      f.set_points(s.x, share(targets, 3, t.offset, t.n));
      ASSERT_EQ(f.local_target_size(), t.n);
      std::vector<double> local(c.nd * t.n * W);
      f.evaluate(s.q, c.nd, kTwoOutputs, local);
      const std::vector<double> all = gather_results(local, c.nd, m, split);
      EXPECT_LE(worst_error(all, exact, kTwoOutputs, m), tolerance) << "against the direct sum, eps " << tolerance;
      EXPECT_LE(worst_error(all, serial, kTwoOutputs, m), tolerance) << "against the serial FMM, eps " << tolerance;
      if (first.empty()) {
        first = all;
      } else {
        EXPECT_EQ(bitwise_mismatches(all, first), 0u) << "the targets' distribution changed the bits";
      }
      EXPECT_EQ(total(f.owned_target_size()), m);
    }
  }
}

// Targets partitioned by the sources' cuts (targets_follow_sources) with sources `c` given as
// `source_split` with partition weights `w` of the whole set (empty: none): within `tolerance` of
// the direct sum; each rank owns exactly the targets that SfcPartition::aligned_with gives it (its
// sources' key range); a repeated evaluation the same bits. Returns the results at all targets.
std::vector<double> expect_aligned_targets(const Cloud& c, const std::vector<double>& w,
                                           const std::vector<double>& targets, const std::vector<double>& exact,
                                           double tolerance, Split source_split, Split target_split) {
  const Share s = share_of(c, source_split);
  const std::vector<double> local_w = w.empty() ? w : share(w, 1, s.part.offset, s.part.n);
  const std::size_t m = targets.size() / 3;
  const Partition t = partition_of(m, target_split);
  const std::vector<double> local_t = share(targets, 3, t.offset, t.n);
  DistributedFmmOptions options = with_tolerance(tolerance);
  options.targets_follow_sources = true;
  DistributedLaplaceFmm f(MPI_COMM_WORLD, options);
  f.set_points(s.x, local_t, local_w);
  std::vector<double> local(c.nd * t.n * W), again(local.size());
  f.evaluate(s.q, c.nd, kTwoOutputs, local);
  f.evaluate(s.q, c.nd, kTwoOutputs, again);
  EXPECT_EQ(bitwise_mismatches(local, again), 0u) << "a repeated evaluation differs";
  const std::vector<double> all = gather_results(local, c.nd, m, target_split);
  EXPECT_LE(worst_error(all, exact, kTwoOutputs, m), tolerance)
      << "against the direct sum, eps " << tolerance << ", " << m << " targets";
  const rpyfmm::mpi::SfcPartition sources(MPI_COMM_WORLD, s.x, local_w);
  const auto aligned = rpyfmm::mpi::SfcPartition::aligned_with(sources, local_t);
  EXPECT_EQ(f.owned_size(), sources.owned_size());
  EXPECT_EQ(f.owned_target_size(), aligned.owned_size()) << "the targets do not follow the sources' cuts";
  if (sources.owned_size() == 0) {
    EXPECT_EQ(f.owned_target_size(), 0u) << "targets on a rank that owns no source";
  }
  return all;
}

TEST(DistributedFmm, TargetsFollowingTheSourcesCuts) {
  // 3000 uniform sources in the unit cube; targets inside it, partly outside it (a cube of side 3
  // around it), clustered (a cube of side 0.04 at one corner and 10 points far away) and on 30
  // sources (those pairs skipped). Each within the tolerance of the direct sum for sources and
  // targets split several ways, with the same bits for every split; on 2 or more ranks the
  // clustered targets' owners differ from their own balanced partition's.
  const Cloud c = uniform_cloud(3000, 2, 50);
  std::vector<std::vector<double>> sets(3);
  std::mt19937_64 rng(51);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int i = 0; i < 3 * 1200; ++i) sets[0].push_back(0.05 + 0.9 * u(rng));
  for (int i = 0; i < 3 * 1200; ++i) sets[1].push_back(3.0 * u(rng) - 1.0);
  for (int i = 0; i < 3 * 1200; ++i) sets[2].push_back(0.6 + 0.1 * u(rng));
  for (int i = 0; i < 3 * 10; ++i) sets[2].push_back(40.0 * u(rng) - 20.0);
  sets[0].insert(sets[0].end(), c.x.begin(), c.x.begin() + 90);
  for (std::size_t k = 0; k < sets.size(); ++k) {
    const std::vector<double>& targets = sets[k];
    const std::size_t m = targets.size() / 3;
    const std::vector<double> exact = direct(c, kTwoOutputs, targets);
    for (double tolerance : {1e-3, 1e-6}) {
      const std::vector<double> first =
          expect_aligned_targets(c, {}, targets, exact, tolerance, Split::even, Split::even);
      for (auto [s, t] :
           {std::pair{Split::last_only, Split::first_empty}, std::pair{Split::geometric, Split::last_only}}) {
        EXPECT_EQ(bitwise_mismatches(expect_aligned_targets(c, {}, targets, exact, tolerance, s, t), first), 0u)
            << "target set " << k << ": the input's distribution changed the bits";
      }
    }
    if (k != 2 || world_size() < 2) continue;
    const Partition t = partition_of(m, Split::even);
    const rpyfmm::mpi::SfcPartition balanced(MPI_COMM_WORLD, share(targets, 3, t.offset, t.n));
    DistributedFmmOptions options = with_tolerance(1e-3);
    options.targets_follow_sources = true;
    DistributedLaplaceFmm f(MPI_COMM_WORLD, options);
    f.set_points(share_of(c, Split::even).x, share(targets, 3, t.offset, t.n));
    std::uint64_t differ = f.owned_target_size() != balanced.owned_size() ? 1 : 0;
    EXPECT_GT(total(differ), 0u) << "clustered targets owned as by their own balanced cuts";
  }
}

TEST(DistributedFmm, TargetsFollowingOwnerlessSources) {
  // One source weight 1e9: on three or more ranks some own no source, and so no target; the
  // results at targets inside and around the sources stay within the tolerance.
  const Cloud c = uniform_cloud(1500, 2, 52);
  std::vector<double> w(c.size(), 1.0);
  w[0] = 1e9;
  std::vector<double> targets = uniform_cloud(900, 1, 53).x;
  for (double& v : targets) v = 2.0 * v - 0.5;
  const std::vector<double> exact = direct(c, kTwoOutputs, targets);
  (void)expect_aligned_targets(c, w, targets, exact, 1e-6, Split::even, Split::geometric);
  const Share s = share_of(c, Split::even);
  const rpyfmm::mpi::SfcPartition sources(MPI_COMM_WORLD, s.x, share(w, 1, s.part.offset, s.part.n));
  std::uint64_t fewest = sources.owned_size();
  MPI_Allreduce(MPI_IN_PLACE, &fewest, 1, MPI_UINT64_T, MPI_MIN, MPI_COMM_WORLD);
  if (world_size() >= 3) {
    EXPECT_EQ(fewest, 0u);
  }
}

TEST(DistributedFmm, TargetsFollowingSourcesAtTheSourcesChangeNothing) {
  // Without targets the option has no effect: the same bits as without it.
  const Cloud c = uniform_cloud(1000, 2, 54);
  DistributedLaplaceFmm plain(MPI_COMM_WORLD, with_tolerance(1e-6));
  DistributedFmmOptions options = with_tolerance(1e-6);
  options.targets_follow_sources = true;
  DistributedLaplaceFmm following(MPI_COMM_WORLD, options);
  EXPECT_EQ(bitwise_mismatches(distributed(following, c, kTwoOutputs, Split::geometric),
                               distributed(plain, c, kTwoOutputs, Split::geometric)),
            0u);
}

TEST(DistributedFmm, EmptyRanksAndMoreRanksThanParticles) {
  const unsigned outputs[] = {fmm::all_outputs};
  for (std::size_t n : {1u, 2u, 3u, 5u, 40u}) {
    const Cloud c = uniform_cloud(n, 1, 14 + n);
    DistributedLaplaceFmm f(MPI_COMM_WORLD, with_tolerance(1e-6));
    for (Split split : {Split::even, Split::last_only, Split::geometric}) {
      const std::vector<double> got = distributed(f, c, outputs, split);
      const std::vector<double> exact = direct(c, outputs);
      if (n == 1) {
        EXPECT_TRUE(std::all_of(got.begin(), got.end(), [](double v) { return v == 0.0; })) << "a lone source";
      } else {
        EXPECT_LE(worst_error(got, exact, outputs, n), 1e-6) << n << " particles";
      }
      EXPECT_EQ(total(f.owned_size()), n);
    }
  }
}

TEST(DistributedFmm, WeightsThatLeaveOwnersEmpty) {
  // One weight 1e9 and the others 1: every cut falls just after that particle, so on three or more
  // ranks some own nothing.
  const Cloud c = uniform_cloud(1500, 1, 15);
  const unsigned outputs[] = {fmm::potential | fmm::gradient};
  const Share s = share_of(c, Split::even);
  std::vector<double> weights(s.part.n, 1.0);
  if (s.part.offset == 0 && s.part.n > 0) weights[0] = 1e9;
  DistributedLaplaceFmm f(MPI_COMM_WORLD, with_tolerance(1e-6));
  f.set_points(s.x, {}, weights);
  std::vector<double> local(s.part.n * W);
  f.evaluate(s.q, 1, outputs, local);
  const std::vector<double> got = gather_results(local, 1, c.size(), Split::even);
  EXPECT_LE(worst_error(got, direct(c, outputs), outputs, c.size()), 1e-6);
  std::uint64_t fewest = f.owned_size();
  MPI_Allreduce(MPI_IN_PLACE, &fewest, 1, MPI_UINT64_T, MPI_MIN, MPI_COMM_WORLD);
  if (world_size() >= 3) {
    EXPECT_EQ(fewest, 0u);
  }
}

TEST(DistributedFmm, MeasuredWeightsRebalanceThePlan) {
  // Weights from the measured per-leaf cost of an evaluation on a clustered cloud: one per input
  // source, finite and >= 0, positive on some rank; a plan built with them meets the tolerance.
  // With separate targets they are refused on every rank, as before any plan.
  const Cloud c = clustered_cloud(800, 1200, 1, 23);
  const unsigned outputs[] = {fmm::potential | fmm::gradient};
  const Share s = share_of(c, Split::geometric);
  DistributedLaplaceFmm f(MPI_COMM_WORLD, with_tolerance(1e-6));
  expect_collective_error([&] { (void)f.measured_weights(); }, ErrorCode::invalid_input, "set_points");
  f.set_points(s.x);
  std::vector<double> local(s.part.n * W);
  f.evaluate(s.q, 1, outputs, local);
  const std::vector<double> weights = f.measured_weights();
  ASSERT_EQ(weights.size(), s.part.n);
  double total = 0.0;
  for (const double w : weights) {
    EXPECT_TRUE(std::isfinite(w) && w >= 0.0) << w;
    total += w;
  }
  MPI_Allreduce(MPI_IN_PLACE, &total, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  EXPECT_GT(total, 0.0);
  f.set_points(s.x, {}, weights);
  f.evaluate(s.q, 1, outputs, local);
  EXPECT_LE(worst_error(gather_results(local, 1, c.size(), Split::geometric), direct(c, outputs), outputs, c.size()),
            1e-6);
  f.set_points(s.x, s.x);
  expect_collective_error([&] { (void)f.measured_weights(); }, ErrorCode::not_supported, "results at the sources");
}

TEST(DistributedFmm, RepeatedEvaluationsAndNewPoints) {
  const Cloud a = uniform_cloud(2000, 3, 16), b = clustered_cloud(500, 1500, 3, 17);
  const unsigned outputs[] = {fmm::potential, fmm::gradient, fmm::all_outputs};
  DistributedLaplaceFmm f(MPI_COMM_WORLD, with_tolerance(1e-6));
  const Share s = share_of(a, Split::geometric);
  const std::vector<double> first = planned_and_evaluated_twice(f, a, s, outputs);
  std::vector<double> again(first.size());
  EXPECT_LE(worst_error(gather_results(first, a.nd, a.size(), Split::geometric), direct(a, outputs), outputs, a.size()),
            1e-6);
  // New points on the same object, then the first ones again: the same plan, the same bits.
  EXPECT_LE(worst_error(distributed(f, b, outputs, Split::even), direct(b, outputs), outputs, b.size()), 1e-6);
  f.set_points(s.x);
  f.evaluate(s.q, a.nd, outputs, again);
  EXPECT_EQ(bitwise_mismatches(first, again), 0u) << "the same points planned again give other bits";
  // Bytes received per evaluation: the charges of the owned sources, the halo and equivalent
  // charges, and the results of this rank's sources in the columns their flags fill (potential 1,
  // gradient 3, all outputs 10 doubles).
  const rpyfmm::mpi::FmmCommunication& comm = f.communication();
  ASSERT_EQ(a.nd, 3u);
  EXPECT_EQ(comm.evaluate_bytes_received,
            8 * a.nd * (f.owned_size() + comm.halo_received + comm.nodes_received) + 8 * (1 + 3 + 10) * s.part.n);
  EXPECT_EQ(f.essential_size(), f.owned_size() == 0 ? 0 : f.owned_size() + comm.halo_received + comm.nodes_received);
  EXPECT_EQ(total(comm.halo_sent), total(comm.halo_received));
  EXPECT_EQ(total(comm.nodes_sent), total(comm.nodes_received));
  EXPECT_EQ(total(comm.cells_sent), total(comm.cells_received));
  for (const char* stage : {"charges", "essential", "results"}) EXPECT_EQ(comm.evaluate_seconds.count(stage), 1u);
}

TEST(DistributedFmm, OverlappedExchangeMeetsTheSameContract) {
  // The serial FMM split into the owned sources' pass (during the exchanges) and the received
  // sources' pass: within the tolerance of the direct sum and the serial FMM on uniform and
  // clustered sets, the same bits for the input on the last rank and on a repeated evaluation, and
  // at separate targets, with per-leaf weights, and with ranks that own nothing.
  const Cloud uniform = uniform_cloud(3000, 2, 11), clustered = clustered_cloud(1200, 4800, 2, 12);
  for (const Cloud* c : {&uniform, &clustered}) {
    const std::vector<double> exact = direct(*c, kTwoOutputs);
    for (double tolerance : {1e-3, 1e-6, 1e-9}) expect_contract(*c, exact, tolerance, kTwoOutputs, true);
  }
  DistributedLaplaceFmm f(MPI_COMM_WORLD, with_tolerance(1e-6, true));
  const Share s = share_of(clustered, Split::geometric);
  std::vector<double> results = planned_and_evaluated_twice(f, clustered, s, kTwoOutputs);
  const std::vector<double> weights = f.measured_weights();
  ASSERT_EQ(weights.size(), s.part.n);
  EXPECT_TRUE(std::all_of(weights.begin(), weights.end(), [](double w) { return std::isfinite(w) && w >= 0.0; }));
  f.set_points(s.x, {}, weights);
  f.evaluate(s.q, clustered.nd, kTwoOutputs, results);
  EXPECT_LE(worst_error(gather_results(results, clustered.nd, clustered.size(), Split::geometric),
                        direct(clustered, kTwoOutputs), kTwoOutputs, clustered.size()),
            1e-6);
  // Targets apart from the sources, and on some of them.
  std::vector<double> targets(uniform.x.begin(), uniform.x.begin() + 30);
  for (std::size_t i = 0; i < 1500; ++i) targets.push_back(0.37 * static_cast<double>(i % 50) - 5.0);
  const std::size_t m = targets.size() / 3;
  const Partition t = partition_of(m, Split::geometric);
  const Share u = share_of(uniform, Split::even);
  f.set_points(u.x, share(targets, 3, t.offset, t.n));
  std::vector<double> local(uniform.nd * t.n * W);
  f.evaluate(u.q, uniform.nd, kTwoOutputs, local);
  EXPECT_LE(worst_error(gather_results(local, uniform.nd, m, Split::geometric), direct(uniform, kTwoOutputs, targets),
                        kTwoOutputs, m),
            1e-6);
  // Fewer particles than ranks: owners without sources, or with nothing received.
  const unsigned all[] = {fmm::all_outputs};
  for (std::size_t n : {2u, 3u, 5u}) {
    const Cloud c = uniform_cloud(n, 1, 14 + n);
    EXPECT_LE(worst_error(distributed(f, c, all, Split::last_only), direct(c, all), all, n), 1e-6) << n;
  }
}

TEST(DistributedFmm, HilbertCurveMeetsTheSameContract) {
  // The sources (and separate targets) partitioned along the Hilbert curve: within the tolerance of
  // the direct sum and the serial FMM on uniform and clustered sets, the same bits for the input on
  // the last rank, on a repeated evaluation and for separate targets distributed two ways.
  const Cloud uniform = uniform_cloud(3000, 2, 11), clustered = clustered_cloud(1200, 4800, 2, 12);
  for (const Cloud* c : {&uniform, &clustered}) {
    const std::vector<double> exact = direct(*c, kTwoOutputs);
    for (double tolerance : {1e-3, 1e-6, 1e-9}) {
      const std::uint64_t cells = expect_contract(*c, exact, tolerance, kTwoOutputs, false, SfcCurve::hilbert);
      if (c == &clustered && world_size() > 1) {
        EXPECT_GT(cells, 0u) << "no cell was compressed at eps " << tolerance;
      }
    }
  }
  DistributedLaplaceFmm f(MPI_COMM_WORLD, with_tolerance(1e-6, false, SfcCurve::hilbert));
  (void)planned_and_evaluated_twice(f, clustered, share_of(clustered, Split::geometric), kTwoOutputs);
  std::vector<double> targets(uniform.x.begin(), uniform.x.begin() + 30);
  for (std::size_t i = 0; i < 1500; ++i) targets.push_back(0.37 * static_cast<double>(i % 50) - 5.0);
  const std::size_t m = targets.size() / 3;
  const std::vector<double> exact = direct(uniform, kTwoOutputs, targets);
  const Share u = share_of(uniform, Split::even);
  std::vector<double> first;
  for (Split split : {Split::last_only, Split::geometric}) {
    const Partition t = partition_of(m, split);
    f.set_points(u.x, share(targets, 3, t.offset, t.n));
    std::vector<double> local(uniform.nd * t.n * W);
    f.evaluate(u.q, uniform.nd, kTwoOutputs, local);
    const std::vector<double> all = gather_results(local, uniform.nd, m, split);
    EXPECT_LE(worst_error(all, exact, kTwoOutputs, m), 1e-6) << "separate targets";
    if (first.empty()) {
      first = all;
    } else {
      EXPECT_EQ(bitwise_mismatches(all, first), 0u) << "the targets' distribution changed the bits";
    }
  }
}

TEST(DistributedFmm, GroupedOutputsAsTheSerialFmm) {
  // The serial FMM's grouped flags pass through: a grad_div group (with potentials and gradients),
  // a plain density and a curl_grad_div group, within twice the tolerance of the serial FMM with
  // the same flags (both within it of the exact sums), with and without the split serial FMM; a
  // group of two refused on every rank.
  const Cloud c = uniform_cloud(3000, 7, 24);
  const unsigned pg = fmm::potential | fmm::gradient | fmm::grad_div;
  const unsigned outputs[] = {
      pg, pg, fmm::grad_div, fmm::gradient, fmm::curl_grad_div, fmm::curl_grad_div, fmm::curl_grad_div};
  const std::vector<double> serial = serial_fmm(c, outputs, 1e-6);
  for (bool overlap_exchange : {false, true}) {
    DistributedLaplaceFmm f(MPI_COMM_WORLD, with_tolerance(1e-6, overlap_exchange));
    const std::vector<double> got = distributed(f, c, outputs, Split::geometric);
    double num = 0.0, den = 0.0;
    for (std::size_t i = 0; i < got.size(); ++i) {
      num += (got[i] - serial[i]) * (got[i] - serial[i]);
      den += serial[i] * serial[i];
    }
    EXPECT_LE(std::sqrt(num / den), 2e-6) << "overlap_exchange " << overlap_exchange;
    // Columns the groups leave at zero stay zero (the curl group's second and third rows).
    for (std::size_t i = 0; i < c.size() * W; ++i) EXPECT_EQ(got[5 * c.size() * W + i], 0.0);
  }
  DistributedLaplaceFmm f(MPI_COMM_WORLD, with_tolerance(1e-6));
  const Share s = share_of(c, Split::even);
  f.set_points(s.x);
  const unsigned two[] = {fmm::grad_div, fmm::grad_div};
  std::vector<double> out(2 * s.part.n * W);
  expect_collective_error([&] { f.evaluate(std::span<const double>(s.q).first(2 * s.part.n), 2, two, out); },
                          ErrorCode::invalid_argument, "groups of three");
}

TEST(DistributedFmm, FailsOnEveryRank) {
  const int last = world_size() - 1;
  const Cloud c = uniform_cloud(300, 1, 18);
  const Share s = share_of(c, Split::even);
  DistributedLaplaceFmm f(MPI_COMM_WORLD);
  std::vector<double> out(s.part.n * W);
  expect_collective_error([&] { f.evaluate(s.q, 1, fmm::potential, out); }, ErrorCode::invalid_input,
                          "set_points has not succeeded");

  std::vector<double> bad_x = s.x;
  if (world_rank() == last && !bad_x.empty()) bad_x[1] = std::numeric_limits<double>::quiet_NaN();
  expect_collective_error([&] { f.set_points(bad_x); }, ErrorCode::invalid_input,
                          "rank " + std::to_string(last) + " of " + std::to_string(world_size()) +
                              ": rpyfmm::mpi::DistributedLaplaceFmm::set_points: local sources entry (0, 1) is NaN");
  expect_collective_error([&] { f.set_points({}); }, ErrorCode::invalid_input, "no rank has a source");
  std::vector<double> ragged_targets(world_rank() == last ? 4 : 3, 0.25);
  expect_collective_error([&] { f.set_points(s.x, ragged_targets); }, ErrorCode::invalid_input,
                          "rank " + std::to_string(last) + " of " + std::to_string(world_size()) +
                              ": rpyfmm::mpi::DistributedLaplaceFmm::set_points: local targets have 4 entries");

  f.set_points(s.x);
  std::vector<double> bad_q = s.q;
  if (world_rank() == last && !bad_q.empty()) bad_q.back() = std::numeric_limits<double>::infinity();
  expect_collective_error([&] { f.evaluate(bad_q, 1, fmm::potential, out); }, ErrorCode::invalid_input,
                          "rank " + std::to_string(last) + " of " + std::to_string(world_size()) +
                              ": rpyfmm::mpi::DistributedLaplaceFmm::evaluate: local charges entry");
  std::vector<double> short_out(world_rank() == 0 ? out.size() + 1 : out.size());
  expect_collective_error([&] { f.evaluate(s.q, 1, fmm::potential, short_out); }, ErrorCode::invalid_input,
                          "rank 0 of " + std::to_string(world_size()) +
                              ": rpyfmm::mpi::DistributedLaplaceFmm::evaluate: local results have");
  if (world_size() > 1) {
    // nd = 2 on the last rank (with arrays of that size), 1 elsewhere.
    const std::size_t nd = world_rank() == last ? 2 : 1;
    std::vector<double> q2(nd * s.part.n, 0.5), out2(nd * s.part.n * W);
    expect_collective_error([&] { f.evaluate(q2, nd, fmm::potential, out2); }, ErrorCode::invalid_argument,
                            "the ranks pass different nd");
  }
  const unsigned flags = world_rank() == last ? fmm::gradient : fmm::potential;
  if (world_size() > 1) {
    expect_collective_error([&] { f.evaluate(s.q, 1, flags, out); }, ErrorCode::invalid_argument,
                            "the ranks pass different outputs");
  }
  DistributedFmmOptions mixed;
  mixed.fmm.tolerance = world_rank() == last ? 1e-3 : 1e-6;
  if (world_size() > 1) {
    expect_collective_error([&] { DistributedLaplaceFmm g(MPI_COMM_WORLD, mixed); }, ErrorCode::invalid_argument,
                            "the ranks pass different options");
    DistributedFmmOptions overlap_on_one;
    overlap_on_one.overlap_exchange = world_rank() == last;
    expect_collective_error([&] { DistributedLaplaceFmm g(MPI_COMM_WORLD, overlap_on_one); },
                            ErrorCode::invalid_argument, "the ranks pass different options");
    DistributedFmmOptions hilbert_on_one;
    hilbert_on_one.curve = world_rank() == last ? SfcCurve::hilbert : SfcCurve::morton;
    expect_collective_error([&] { DistributedLaplaceFmm g(MPI_COMM_WORLD, hilbert_on_one); },
                            ErrorCode::invalid_argument, "the ranks pass different options");
  }
  {
    DistributedFmmOptions bad_curve;
    bad_curve.curve = static_cast<SfcCurve>(world_rank() == last ? 7 : 0);
    expect_collective_error([&] { DistributedLaplaceFmm g(MPI_COMM_WORLD, bad_curve); }, ErrorCode::invalid_argument,
                            "curve must be SfcCurve::morton or SfcCurve::hilbert, got 7");
  }
  // Still usable after the failures.
  f.evaluate(s.q, 1, fmm::potential, out);
  const unsigned pot[] = {fmm::potential};
  EXPECT_LE(worst_error(gather_results(out, 1, c.size(), Split::even), direct(c, pot), pot, c.size()), 1e-6);
}

}  // namespace
