// rpyfmm::mpi::DistributedFmmRpy against independent references on the whole set: the exact
// product of the serial rpy::DirectRpy (the contract: relative l2 error over all particles at most
// the tolerance) and the serial rpy::FmmRpy (both within the tolerance of the exact product, so
// within twice it of each other). Uniform, strongly clustered and polydisperse sets, overlapping
// and touching pairs whose partners lie on different ranks, coincident points, more ranks than
// particles, extreme length scales and loads; repeated products and thread counts bit for bit; the
// partition along the Hilbert curve; the samplers on the operator; and collective failure on bad
// input of one rank.
#include <gtest/gtest.h>
#include <mpi.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "fmm_plan.hpp"  // mpi/src: the owners' serial FMMs, for the leaves' capacity
#include "mpi_test_support.hpp"
#include "rpyfmm/mpi/direct_operator.hpp"
#include "rpyfmm/mpi/fmm_rpy.hpp"
#include "rpyfmm/mpi/sqrt.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"

using rpyfmm::ErrorCode;
using rpyfmm::mpi::DistributedFmmRpy;
using rpyfmm::mpi::DistributedFmmRpyOptions;
using rpyfmm::mpi::SfcCurve;
using rpyfmm::rpy::DirectRpy;
using rpyfmm::rpy::FmmRpy;
using rpyfmm::rpy::Geometry;
using rpyfmm::rpy::SqrtMethod;
using rpyfmm::rpy::SqrtPreconditioner;
using rpyfmm::rpy::to_string;
using namespace rpyfmm_mpi_test;

namespace {

constexpr double kTolerances[] = {1e-3, 1e-6, 1e-9};
constexpr int kLeaf = 24;

// The serial products on the whole set: exact (DirectRpy) and FmmRpy at `tolerance`.
struct SerialProducts {
  std::vector<double> exact, fmm;
};

SerialProducts serial_products(const Particles& p, double tolerance) {
  SerialProducts s{std::vector<double>(3 * p.size()), std::vector<double>(3 * p.size())};
  DirectRpy direct(Geometry::open(), kViscosity);
  direct.set_positions(p.x, p.a);
  direct.apply(p.f, s.exact);
  FmmRpy fmm(Geometry::open(), kViscosity, {.tolerance = tolerance, .leaf_capacity = kLeaf});
  fmm.set_positions(p.x, p.a);
  fmm.apply(p.f, s.fmm);
  return s;
}

// Distributes `p` by `split`, applies the operator at `tolerance` and checks the contract on every
// rank: error against the exact product <= tolerance, against serial FmmRpy <= 2 tolerance, and a
// repeated product bit for bit. Rank 0 prints the measured errors. Returns this rank's velocities.
// Each owner's serial Laplace FMM runs with leaves of kLeaf points, so that at these sizes most pairs
// are in its far field (its automatic leaves hold hundreds of points at 1e-6 and 1e-9).
std::vector<double> expect_contract(const Particles& p, Split split, double tolerance, const char* label,
                                    bool overlap_exchange = false, SfcCurve curve = SfcCurve::morton) {
  const Partition part = partition_of(p.size(), split);
  const SerialProducts serial = serial_products(p, tolerance);
  DistributedFmmRpy op(
      MPI_COMM_WORLD, kViscosity,
      {.tolerance = tolerance, .leaf_capacity = kLeaf, .overlap_exchange = overlap_exchange, .curve = curve});
  op.set_positions(share(p.x, 3, part.offset, part.n), share(p.a, 1, part.offset, part.n));
  EXPECT_EQ(op.global_size(), p.size());
  EXPECT_EQ(op.local_size(), part.n);
  EXPECT_EQ(op.offset(), part.offset);
  const std::vector<double> f = share(p.f, 3, part.offset, part.n);
  std::vector<double> u(3 * part.n, std::numeric_limits<double>::quiet_NaN()), again(u.size());
  op.apply(f, u);
  op.apply(f, again);
  EXPECT_EQ(bitwise_mismatches(u, again), 0u) << "repeated product, rank " << world_rank();
  const double to_exact = global_relative_error(u, share(serial.exact, 3, part.offset, part.n));
  const double to_fmm = global_relative_error(u, share(serial.fmm, 3, part.offset, part.n));
  EXPECT_LE(to_exact, tolerance) << label << " against DirectRpy";
  EXPECT_LE(to_fmm, 2.0 * tolerance) << label << " against FmmRpy";
  if (world_rank() == 0) {
    std::printf("[fmm-rpy] %-22s P=%d eps=%.0e: error vs DirectRpy %.2e, vs FmmRpy %.2e, halo %zu\n", label,
                world_size(), tolerance, to_exact, to_fmm, op.halo_size());
  }
  return u;
}

// The whole set's velocities on every rank from each rank's share of the input split by `split`.
std::vector<double> all_velocities(const std::vector<double>& local, std::size_t n, Split split) {
  const Partition part = partition_of(n, split);
  std::vector<double> mine(3 * n, 0.0), all(3 * n);
  std::copy(local.begin(), local.end(), mine.begin() + static_cast<std::ptrdiff_t>(3 * part.offset));
  MPI_Allreduce(mine.data(), all.data(), static_cast<int>(mine.size()), MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  return all;
}

}  // namespace

TEST(MpiDistributedFmmRpy, UniformCloudWithinToleranceOfDirect) {
  // Equal radii, volume fraction about 0.09: a few overlapping pairs.
  const Particles p = uniform_particles(600, 30.0, 1.0, 1.0, 61);
  for (double eps : kTolerances) {
    expect_contract(p, Split::even, eps, "uniform, even");
    expect_contract(p, Split::last_only, eps, "uniform, last only");
  }
}

TEST(MpiDistributedFmmRpy, OverlappedExchangeWithinToleranceOfDirect) {
  // The Laplace FMM's serial FMM split to run during the exchanges: the same contract.
  const Particles uniform = uniform_particles(600, 30.0, 1.0, 1.0, 61), clustered = clustered_particles(300, 60, 62);
  for (double eps : kTolerances) {
    expect_contract(uniform, Split::even, eps, "uniform, overlapped", true);
    expect_contract(clustered, Split::last_only, eps, "clustered, overlapped", true);
  }
}

TEST(MpiDistributedFmmRpy, StronglyClusteredWithinToleranceOfDirect) {
  // 300 overlapping spheres of radii 0.5 ... 2 in a ball of radius 3 (partial overlaps, spheres
  // inside others, a coincident pair) and 60 far away; with last_only the cluster is on one rank.
  const Particles p = clustered_particles(300, 60, 62);
  for (double eps : kTolerances) {
    expect_contract(p, Split::geometric, eps, "clustered, geometric");
    expect_contract(p, Split::last_only, eps, "clustered, last only");
  }
}

TEST(MpiDistributedFmmRpy, PolydisperseRadiiRatio16WithinToleranceOfDirect) {
  // Radii from 0.25 to 4 (ratio 16): seven Laplace densities, small spheres inside large ones; a
  // cube of side 70, so that the FMM's leaves (at least 2 a_max = 8 wide) leave pairs to its far field.
  const Particles p = uniform_particles(500, 70.0, 0.25, 4.0, 63);
  for (double eps : kTolerances) expect_contract(p, Split::even, eps, "polydisperse 16");
}

TEST(MpiDistributedFmmRpy, OverlappingAndTouchingPairsAcrossRanks) {
  // 150 pairs overlapping at 0.6 (a_i + a_j), 150 touching (r = a_i + a_j): with the even split each
  // pair's partners are on different ranks of the input, and across the owners' cuts for some.
  for (double gap : {0.6, 1.0}) {
    const Particles p = pairs_at(150, 40.0, gap, 64);
    for (double eps : kTolerances) expect_contract(p, Split::even, eps, gap < 1.0 ? "overlapping pairs" : "touching");
  }
}

TEST(MpiDistributedFmmRpy, CoincidentPointsWithinToleranceOfDirect) {
  // Particle i + 150 on particle i (r = 0: in the exact near field, the block I / (6 pi eta max(a))).
  Particles p = uniform_particles(300, 12.0, 0.5, 1.5, 65);
  for (std::size_t i = 0; i < 150; ++i)
    for (std::size_t d = 0; d < 3; ++d) p.x[3 * (i + 150) + d] = p.x[3 * i + d];
  for (double eps : kTolerances) expect_contract(p, Split::even, eps, "coincident");
  for (double& a : p.a) a = 1.0;
  expect_contract(p, Split::first_empty, 1e-6, "coincident, equal radii");
}

// Particle i + 150 at `ratio` a_i from particle i (along x).
Particles nearly_coincident(double ratio) {
  Particles p = uniform_particles(300, 12.0, 0.5, 1.5, 67);
  for (std::size_t i = 0; i < 150; ++i)
    for (std::size_t d = 0; d < 3; ++d) p.x[3 * (i + 150) + d] = p.x[3 * i + d] + (d == 0 ? ratio * p.a[i] : 0.0);
  return p;
}

TEST(MpiDistributedFmmRpy, NearlyCoincidentPointsWithinTolerance) {
  // Every overlapping pair lies in the owners' exact near field (leaves at least 2 a_max wide, no
  // compressed cell within 2 a_max of a rank's region), summed as RPY blocks with no far form to
  // cancel: pairs at r = 0.05 a, 1e-3 a and 1e-9 a are within every tolerance.
  for (double ratio : {0.05, 1e-3, 1e-9}) {
    const Particles near = nearly_coincident(ratio);
    for (double eps : kTolerances) expect_contract(near, Split::even, eps, "nearly coincident");
  }
}

namespace {

// Every near pair of the owners' serial FMMs, those with equivalent nodes of compressed cells
// included: leaves of more points than a rank holds (one leaf per owner, so every source is in its
// near field), and cells compressed where far from a region. On one rank nothing is compressed. Checks the contract
// against DirectRpy (U, and W with torques) and returns the nodes all ranks received.
std::uint64_t expect_one_leaf_contract(const Particles& p, const std::vector<double>& t, double tolerance) {
  const Partition part = partition_of(p.size(), Split::even);
  DirectRpy direct(Geometry::open(), kViscosity);
  direct.set_positions(p.x, p.a);
  std::vector<double> exact_u(3 * p.size()), exact_w(3 * p.size()), exact_f(3 * p.size());
  direct.apply(p.f, t, exact_u, exact_w);
  direct.apply(p.f, exact_f);
  DistributedFmmRpy op(MPI_COMM_WORLD, kViscosity, {.tolerance = tolerance, .leaf_capacity = 1 << 20});
  op.set_positions(share(p.x, 3, part.offset, part.n), share(p.a, 1, part.offset, part.n));
  const std::vector<double> f = share(p.f, 3, part.offset, part.n), tl = share(t, 3, part.offset, part.n);
  std::vector<double> u(3 * part.n), w(3 * part.n), uf(3 * part.n);
  op.apply(f, uf);
  op.apply(f, tl, u, w);
  const double e_f = global_relative_error(uf, share(exact_f, 3, part.offset, part.n));
  const double e_u = global_relative_error(u, share(exact_u, 3, part.offset, part.n));
  const double e_w = global_relative_error(w, share(exact_w, 3, part.offset, part.n));
  EXPECT_LE(e_f, tolerance) << "U from forces";
  EXPECT_LE(e_u, tolerance) << "U with torques";
  EXPECT_LE(e_w, tolerance) << "W";
  std::uint64_t nodes = op.laplace().communication().nodes_received, all = 0;
  MPI_Allreduce(&nodes, &all, 1, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD);
  if (world_rank() == 0) {
    std::printf("[fmm-rpy] one leaf per owner P=%d eps=%.0e: nodes %llu, error U %.2e, with torques U %.2e W %.2e\n",
                world_size(), tolerance, static_cast<unsigned long long>(all), e_f, e_u, e_w);
  }
  return all;
}

}  // namespace

TEST(MpiDistributedFmmRpy, EquivalentNodesInTheNearFieldSummedAsLaplacePairs) {
  // Two clusters of 400 overlapping spheres (radii 0.5 ... 1.5, cubes of side 10) 100 apart: on
  // two or more ranks each cluster's cells reach the other cluster's owners compressed (a cell of
  // half-side about 5 at distance about 90 needs 3^3 nodes at 1e-3, 5^3 at 1e-6), and with one leaf
  // per owner their nodes are near sources, summed as Laplace pairs of the densities (the
  // compression error is below tolerance / 100, docs/mpi.md "Distributed Laplace FMM", error rule).
  Particles p = uniform_particles(400, 10.0, 0.5, 1.5, 74);
  const Particles other = uniform_particles(400, 10.0, 0.5, 1.5, 75);
  for (std::size_t i = 0; i < other.size(); ++i) {
    for (std::size_t d = 0; d < 3; ++d) {
      p.x.push_back(other.x[3 * i + d] + (d == 0 ? 100.0 : 0.0));
      p.f.push_back(other.f[3 * i + d]);
    }
    p.a.push_back(other.a[i]);
  }
  std::vector<double> t(p.f.size());
  for (std::size_t i = 0; i < t.size(); ++i) t[i] = p.a[i / 3] * std::cos(0.7 * static_cast<double>(i));
  for (double eps : {1e-3, 1e-6}) {
    const std::uint64_t nodes = expect_one_leaf_contract(p, t, eps);
    if (world_size() > 1) {
      EXPECT_GT(nodes, 0u) << "no cell compressed: the test does not reach the node pairs";
    }
  }
}

TEST(MpiDistributedFmmRpy, MoreRanksThanParticles) {
  for (std::size_t n : {1, 2, 3}) {
    const Particles p = uniform_particles(n, 3.0, 0.8, 1.2, 66 + n);  // overlapping
    for (Split s : kSplits) expect_contract(p, s, 1e-6, "1-3 particles");
  }
}

TEST(MpiDistributedFmmRpy, ExtremeLengthScalesAndLoads) {
  // Extent 1e137 and radii 1e135 (the far field's a^2 T terms underflow in plain units: evaluated
  // in units of a power of two, as FmmRpy does), and forces near 1e300 (scaled by a power of two).
  Particles p = uniform_particles(300, 1.0, 0.002, 0.004, 70);
  for (double& x : p.x) x *= 1e137;
  for (double& a : p.a) a *= 1e137;
  expect_contract(p, Split::geometric, 1e-6, "extent 1e137");
  Particles q = uniform_particles(300, 30.0, 1.0, 1.0, 71);
  for (double& f : q.f) f *= 1e300;
  expect_contract(q, Split::even, 1e-6, "forces 1e300");
}

TEST(MpiDistributedFmmRpy, ResultsIndependentOfThreadCountAndDistribution) {
  const Particles p = clustered_particles(200, 40, 72);
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  const std::vector<double> one = expect_contract(p, Split::even, 1e-6, "1 thread");
  omp_set_num_threads(3);
  const std::vector<double> three = expect_contract(p, Split::even, 1e-6, "3 threads");
  omp_set_num_threads(saved);
  EXPECT_EQ(bitwise_mismatches(one, three), 0u);
  // The same global input distributed otherwise over the same ranks: the same bits.
  const std::vector<double> other = expect_contract(p, Split::last_only, 1e-6, "last only");
  EXPECT_EQ(
      bitwise_mismatches(all_velocities(one, p.size(), Split::even), all_velocities(other, p.size(), Split::last_only)),
      0u);
}

TEST(MpiDistributedFmmRpy, HilbertCurveWithinToleranceOfDirect) {
  // The partition along the Hilbert curve: the same contract on the uniform and the strongly
  // clustered sets, and the same bits whichever way the input is distributed over the ranks.
  const Particles uniform = uniform_particles(600, 30.0, 1.0, 1.0, 61), clustered = clustered_particles(300, 60, 62);
  for (double eps : kTolerances) {
    const std::vector<double> even =
        expect_contract(uniform, Split::even, eps, "uniform, hilbert", false, SfcCurve::hilbert);
    const std::vector<double> last =
        expect_contract(uniform, Split::last_only, eps, "uniform, hilbert, last", false, SfcCurve::hilbert);
    EXPECT_EQ(bitwise_mismatches(all_velocities(even, uniform.size(), Split::even),
                                 all_velocities(last, uniform.size(), Split::last_only)),
              0u);
    expect_contract(clustered, Split::geometric, eps, "clustered, hilbert", false, SfcCurve::hilbert);
  }
}

TEST(MpiDistributedFmmRpy, SamplersOnTheOperator) {
  // w by Lanczos and Chebyshev at 1e-6, each without and with the block preconditioner (the serial
  // blocks of all ranks' particles), on the FMM operator at 1e-9 against the same sampler on the exact
  // DistributedDirectRpy (the same blocks: the same particles). The operators differ by <= 1e-9
  // relative, which moves the root (and the estimated Chebyshev bounds) by about that over the
  // smallest eigenvalue's square root, far below the samplers' 1e-6; each sampler stops within its
  // tolerance of its own root, so the two lie within 1e-5 of each other.
  const Particles p = clustered_particles(150, 30, 73);
  const Partition part = partition_of(p.size(), Split::even);
  const std::vector<double> x = share(p.x, 3, part.offset, part.n), a = share(p.a, 1, part.offset, part.n);
  DistributedFmmRpy fmm(MPI_COMM_WORLD, kViscosity, {.tolerance = 1e-9});
  fmm.set_positions(x, a);
  rpyfmm::mpi::DistributedDirectRpy direct(MPI_COMM_WORLD, kViscosity);
  direct.set_positions(x, a);
  std::vector<double> z(3 * part.n), w_fmm(z.size()), w_direct(z.size());
  rpyfmm::mpi::fill_normal(z, part.offset, 5, 0);
  for (SqrtMethod method : {SqrtMethod::lanczos, SqrtMethod::chebyshev}) {
    for (SqrtPreconditioner preconditioner : {SqrtPreconditioner::none, SqrtPreconditioner::block}) {
      rpyfmm::rpy::SqrtOptions options;
      options.method = method;
      options.preconditioner = preconditioner;
      options.tolerance = 1e-6;
      const rpyfmm::rpy::SqrtReport on_fmm = rpyfmm::mpi::sqrt_apply(fmm, z, w_fmm, options);
      const rpyfmm::rpy::SqrtReport on_direct = rpyfmm::mpi::sqrt_apply(direct, z, w_direct, options);
      EXPECT_EQ(on_fmm.preconditioner_blocks, on_direct.preconditioner_blocks);
      const double difference = global_relative_error(w_fmm, w_direct);
      EXPECT_LE(difference, 1e-5) << to_string(method) << ", " << to_string(preconditioner);
      if (world_rank() == 0) {
        std::printf("[fmm-rpy] %s (%s) on FMM vs direct: %.2e\n", to_string(method), to_string(preconditioner),
                    difference);
      }
    }
  }
}

// ------------------------------------------------------------------------------- rotation ---

namespace {

// Torques of the whole set: a_i times uniform entries in [-1, 1] (a torque is a force times a
// length, so that U's parts from F and from T, and W's from F and from T, are of one order).
std::vector<double> torques_of(const Particles& p, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> t(3 * p.size());
  for (std::size_t i = 0; i < t.size(); ++i) t[i] = p.a[i / 3] * u(rng);
  return t;
}

// This rank's U and W, and the errors of each against the exact product.
struct GrandResult {
  std::vector<double> u, w;
  double u_error = 0.0, w_error = 0.0;
};

// Distributes `p` with torques `t` by `split`, applies [U; W] = M [F; T] at `tolerance` and checks on
// every rank: the relative l2 errors of U and of W (each over all particles) against the exact
// grand product of the serial DirectRpy (independent: every pair's exact blocks summed directly,
// rpy/src/direct_rotation.cpp) at most the tolerance; a repeated product bit for bit; and with zero
// torques the velocities of the translational apply bit for bit (the torque densities are zero, so
// the far field's translational sums and the near field's translational blocks are the same
// operations on the same values, each plus an exact zero). Rank 0 prints the errors.
GrandResult expect_rotation_contract(const Particles& p, const std::vector<double>& t, Split split, double tolerance,
                                     const char* label) {
  const Partition part = partition_of(p.size(), split);
  DirectRpy direct(Geometry::open(), kViscosity);
  direct.set_positions(p.x, p.a);
  std::vector<double> exact_u(3 * p.size()), exact_w(3 * p.size());
  direct.apply(p.f, t, exact_u, exact_w);
  DistributedFmmRpy op(MPI_COMM_WORLD, kViscosity, {.tolerance = tolerance, .leaf_capacity = kLeaf});
  EXPECT_TRUE(op.supports_rotation());
  op.set_positions(share(p.x, 3, part.offset, part.n), share(p.a, 1, part.offset, part.n));
  const std::vector<double> f = share(p.f, 3, part.offset, part.n), tl = share(t, 3, part.offset, part.n);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> u(3 * part.n, nan), w(3 * part.n, nan), u2(u.size(), nan), w2(u.size(), nan);
  op.apply(f, tl, u, w);
  op.apply(f, tl, u2, w2);
  EXPECT_EQ(bitwise_mismatches(u, u2) + bitwise_mismatches(w, w2), 0u) << "repeated product, rank " << world_rank();
  GrandResult e{u, w};
  e.u_error = global_relative_error(u, share(exact_u, 3, part.offset, part.n));
  e.w_error = global_relative_error(w, share(exact_w, 3, part.offset, part.n));
  EXPECT_LE(e.u_error, tolerance) << label << ": U against DirectRpy";
  EXPECT_LE(e.w_error, tolerance) << label << ": W against DirectRpy";
  const std::vector<double> zero(tl.size(), 0.0);
  std::vector<double> translational(u.size(), nan);
  op.apply(f, zero, u2, w2);
  op.apply(f, translational);
  EXPECT_EQ(bitwise_mismatches(u2, translational), 0u) << label << ": zero torques, rank " << world_rank();
  if (world_rank() == 0) {
    std::printf("[fmm-rpy] rotation %-22s P=%d eps=%.0e: error vs DirectRpy U %.2e, W %.2e\n", label, world_size(),
                tolerance, e.u_error, e.w_error);
  }
  return e;
}

}  // namespace

TEST(MpiDistributedFmmRpyRotation, UniformAndClusteredWithinToleranceOfDirect) {
  // Equal radii at volume fraction 0.09 (a few overlapping pairs); the cluster of 300 spheres of radii
  // 0.5 ... 2 in a ball of radius 3 (partial overlaps, spheres inside others, a coincident pair) with
  // 60 far away, on one rank (last only) or cut across the ranks (geometric).
  const Particles uniform = uniform_particles(600, 30.0, 1.0, 1.0, 161), clustered = clustered_particles(300, 60, 162);
  const std::vector<double> tu = torques_of(uniform, 261), tc = torques_of(clustered, 262);
  for (double eps : kTolerances) {
    expect_rotation_contract(uniform, tu, Split::even, eps, "uniform, even");
    expect_rotation_contract(uniform, tu, Split::last_only, eps, "uniform, last only");
    expect_rotation_contract(clustered, tc, Split::geometric, eps, "clustered, geometric");
    expect_rotation_contract(clustered, tc, Split::last_only, eps, "clustered, last only");
  }
}

TEST(MpiDistributedFmmRpyRotation, PolydisperseRadiiRatio16WithinToleranceOfDirect) {
  // Radii 0.25 ... 4: seven translational densities and the torques', small spheres inside large
  // ones (the coupling r / (8 pi a_j^3) of a sphere inside another, the far form's 1 / r^2 taken back).
  const Particles p = uniform_particles(500, 70.0, 0.25, 4.0, 163);
  const std::vector<double> t = torques_of(p, 263);
  for (double eps : kTolerances) expect_rotation_contract(p, t, Split::even, eps, "polydisperse 16");
}

TEST(MpiDistributedFmmRpyRotation, OverlappingTouchingAndCoincidentPairs) {
  // 150 pairs overlapping at 0.6 (a_i + a_j) and 150 touching, partners on different ranks; then 150
  // coincident pairs (r = 0: in the exact near field, the block 1 / (8 pi eta max(a)^3)), with rank 0
  // owning nothing in the equal-radii case.
  for (double gap : {0.6, 1.0}) {
    const Particles p = pairs_at(150, 40.0, gap, 164);
    const std::vector<double> t = torques_of(p, 264);
    for (double eps : kTolerances)
      expect_rotation_contract(p, t, Split::even, eps, gap < 1.0 ? "overlapping pairs" : "touching");
  }
  Particles p = uniform_particles(300, 12.0, 0.5, 1.5, 65);
  for (std::size_t i = 0; i < 150; ++i)
    for (std::size_t d = 0; d < 3; ++d) p.x[3 * (i + 150) + d] = p.x[3 * i + d];
  const std::vector<double> t = torques_of(p, 265);
  for (double eps : kTolerances) expect_rotation_contract(p, t, Split::even, eps, "coincident");
  for (double& a : p.a) a = 1.0;
  expect_rotation_contract(p, torques_of(p, 266), Split::first_empty, 1e-6, "coincident, equal radii");
}

TEST(MpiDistributedFmmRpyRotation, NearlyCoincidentPointsWithinTolerance) {
  // The overlapping pairs' exact grand blocks in the owners' near field: pairs at r = 0.05 a,
  // 1e-3 a and 1e-9 a within every tolerance, for U and W.
  for (double ratio : {0.05, 1e-3, 1e-9}) {
    const Particles near = nearly_coincident(ratio);
    const std::vector<double> t = torques_of(near, 267);
    for (double eps : kTolerances) expect_rotation_contract(near, t, Split::even, eps, "nearly coincident");
  }
}

TEST(MpiDistributedFmmRpyRotation, MoreRanksThanParticles) {
  for (std::size_t n : {1, 2, 3}) {
    const Particles p = uniform_particles(n, 3.0, 0.8, 1.2, 166 + n);  // overlapping
    for (Split s : kSplits) expect_rotation_contract(p, torques_of(p, 266 + n), s, 1e-6, "1-3 particles");
  }
}

TEST(MpiDistributedFmmRpyRotation, ExtremeLengthScalesAndLoads) {
  // Extent 1e137 and radii 1e135 (in units of a power of two 2^e: U carries 2^-e, W 2^-2e), torques
  // of the same length scale; loads near 1e300 (one power of two for forces and torques).
  Particles p = uniform_particles(300, 1.0, 0.002, 0.004, 170);
  for (double& x : p.x) x *= 1e137;
  for (double& a : p.a) a *= 1e137;
  expect_rotation_contract(p, torques_of(p, 270), Split::geometric, 1e-6, "extent 1e137");
  Particles q = uniform_particles(300, 30.0, 1.0, 1.0, 171);
  for (double& f : q.f) f *= 1e300;
  std::vector<double> t = torques_of(q, 271);
  for (double& v : t) v *= 1e300;
  expect_rotation_contract(q, t, Split::even, 1e-6, "loads 1e300");
}

TEST(MpiDistributedFmmRpyRotation, ResultsIndependentOfThreadCountAndDistribution) {
  // U and W on 1 and 3 threads, and with the input on the last rank only, the same bits (the
  // Laplace FMM's and the near field's sums run in a fixed order per particle).
  const Particles p = clustered_particles(200, 40, 172);
  const std::vector<double> t = torques_of(p, 272);
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  const GrandResult one = expect_rotation_contract(p, t, Split::even, 1e-6, "1 thread");
  omp_set_num_threads(3);
  const GrandResult three = expect_rotation_contract(p, t, Split::even, 1e-6, "3 threads");
  omp_set_num_threads(saved);
  EXPECT_EQ(bitwise_mismatches(one.u, three.u) + bitwise_mismatches(one.w, three.w), 0u);
  const GrandResult other = expect_rotation_contract(p, t, Split::last_only, 1e-6, "last only");
  const Partition even = partition_of(p.size(), Split::even), last = partition_of(p.size(), Split::last_only);
  // Both distributions' results gathered into the global order on every rank.
  const auto gathered = [&](const std::vector<double>& mine, const Partition& part) {
    std::vector<double> all(3 * p.size(), 0.0), sum(all.size());
    std::copy(mine.begin(), mine.end(), all.begin() + static_cast<std::ptrdiff_t>(3 * part.offset));
    MPI_Allreduce(all.data(), sum.data(), static_cast<int>(all.size()), MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
    return sum;
  };
  EXPECT_EQ(bitwise_mismatches(gathered(one.u, even), gathered(other.u, last)), 0u);
  EXPECT_EQ(bitwise_mismatches(gathered(one.w, even), gathered(other.w, last)), 0u);
}

TEST(MpiDistributedFmmRpy, OwnedPairsOnceBesideHaloPairs) {
  // Sets large enough that each owner's serial FMM has at least 64 leaves (FmmRpy's threshold for
  // evaluating a leaf pair once for both directions, rpy/src/fmm_near_field.cpp), with halo particles
  // among the near sources of its owned leaves on 2-4 ranks: the owned pairs are summed once for
  // both directions, the halo particles one-sided (docs/mpi.md, "Distributed FmmRpy"). Equal radii
  // (volume fraction about 0.09) and radii 0.5 - 1.5 (seven densities, the unequal-radii kernels):
  // the contract of expect_contract, U and W against DirectRpy, and 1 and 3 threads bit for bit
  // (the symmetric tasks run in colours, each velocity's contributions in a fixed order).
  const Particles equal = uniform_particles(2000, 45.0, 1.0, 1.0, 73);
  const Particles unequal = uniform_particles(2000, 45.0, 0.5, 1.5, 74);
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  std::vector<double> one;
  for (double eps : {1e-3, 1e-6}) {
    expect_contract(equal, Split::even, eps, "2000, equal radii");
    one = expect_contract(unequal, Split::even, eps, "2000, radii 0.5-1.5");
  }
  expect_rotation_contract(equal, torques_of(equal, 273), Split::even, 1e-6, "2000, equal radii");
  expect_rotation_contract(unequal, torques_of(unequal, 274), Split::even, 1e-6, "2000, radii 0.5-1.5");
  omp_set_num_threads(3);
  const std::vector<double> three = expect_contract(unequal, Split::even, 1e-6, "3 threads");
  omp_set_num_threads(saved);
  EXPECT_EQ(bitwise_mismatches(one, three), 0u);
}

TEST(MpiDistributedFmmRpy, OwnersLeavesCountOwnedParticlesOnce) {
  // FmmRpy's leaf capacity counts particles. An owner whose serial Laplace FMM received halo
  // particles runs it at its owned particles as separate targets, a tree that counts a leaf's
  // sources and targets together, so there the capacity is doubled (DistributedFmmOptions::
  // count_owned_once): a leaf of owned particles then splits at kLeaf particles, as in FmmRpy. At
  // its own points (one rank, nothing received) the capacity stays kLeaf. Every leaf holds at most
  // kLeaf owned particles either way; the contract on these sets is expect_contract's (above).
  const Particles p = uniform_particles(2000, 45.0, 1.0, 1.0, 73);
  const Partition part = partition_of(p.size(), Split::even);
  DistributedFmmRpy op(MPI_COMM_WORLD, kViscosity, {.tolerance = 1e-6, .leaf_capacity = kLeaf});
  op.set_positions(share(p.x, 3, part.offset, part.n), share(p.a, 1, part.offset, part.n));
  const rpyfmm::mpi::DistributedLaplaceFmm::Plan* plan = op.laplace().plan();
  ASSERT_NE(plan, nullptr);
  ASSERT_GT(plan->sources, 0u);
  const bool received = plan->sources > plan->owned_x.size() / 3;
  EXPECT_EQ(received, world_size() > 1) << "rank " << world_rank();
  EXPECT_EQ(plan->fmm.stats().leaf_capacity, received ? 2 * kLeaf : kLeaf) << "rank " << world_rank();
  const rpyfmm::fmm::NearField& near = plan->fmm.near_field();
  std::size_t most = 0;
  for (std::size_t leaf = 0; leaf < near.num_leaves(); ++leaf) most = std::max(most, near.targets(leaf).size());
  EXPECT_LE(most, static_cast<std::size_t>(kLeaf)) << "rank " << world_rank();
}

// ----------------------------------------------------------------------- collective errors ---

namespace {

std::string rank_of(int r) {
  return "rank " + std::to_string(r) + " of " + std::to_string(world_size()) + ": ";
}

}  // namespace

TEST(MpiDistributedFmmRpy, BadInputOnOneRankFailsEveryRankThenRecovers) {
  const int last = world_size() - 1;
  const Particles p = uniform_particles(40, 10.0, 1.0, 1.0, 80);
  const Partition part = partition_of(p.size(), Split::even);
  const std::vector<double> x = share(p.x, 3, part.offset, part.n), a = share(p.a, 1, part.offset, part.n);
  const std::vector<double> f = share(p.f, 3, part.offset, part.n);
  DistributedFmmRpy op(MPI_COMM_WORLD, kViscosity, {.tolerance = 1e-6});
  std::vector<double> u(f.size());
  expect_collective_error([&] { op.apply(f, u); }, ErrorCode::invalid_input, "positions not set");

  std::vector<double> bad_x = x;
  if (world_rank() == last) bad_x[3 * 2 + 1] = std::numeric_limits<double>::quiet_NaN();
  expect_collective_error(
      [&] { op.set_positions(bad_x, a); }, ErrorCode::invalid_input,
      rank_of(last) + "rpyfmm::mpi::DistributedFmmRpy::set_positions: local positions entry (2, 1) is NaN");
  EXPECT_EQ(op.global_size(), 0u);
  std::vector<double> bad_a = a;
  if (world_rank() == 0) bad_a[0] = -1.0;
  expect_collective_error([&] { op.set_positions(x, bad_a); }, ErrorCode::invalid_argument,
                          rank_of(0) + "rpyfmm::mpi::DistributedFmmRpy::set_positions: radius of local particle 0");
  std::vector<double> short_a = a;
  if (world_rank() == last) short_a.pop_back();
  expect_collective_error([&] { op.set_positions(x, short_a); }, ErrorCode::invalid_input, rank_of(last));

  op.set_positions(x, a);
  std::vector<double> bad_f = f;
  if (world_rank() == 0) bad_f[4] = std::numeric_limits<double>::infinity();
  expect_collective_error([&] { op.apply(bad_f, u); }, ErrorCode::invalid_input,
                          rank_of(0) + "rpyfmm::mpi::DistributedFmmRpy::apply: local forces entry (1, 1) is infinite");
  std::vector<double> short_u(world_rank() == last ? u.size() + 3 : u.size());
  expect_collective_error([&] { op.apply(f, short_u); }, ErrorCode::invalid_input, rank_of(last));
  EXPECT_NO_THROW(op.apply(f, u));
  const std::vector<double> none;
  expect_collective_error([&] { op.set_positions(none, none); }, ErrorCode::invalid_input, "no particles on any");
}

TEST(MpiDistributedFmmRpyRotation, BadInputOnOneRankFailsEveryRank) {
  const int last = world_size() - 1;
  const Particles p = uniform_particles(40, 10.0, 1.0, 1.0, 180);
  const Partition part = partition_of(p.size(), Split::even);
  const std::vector<double> x = share(p.x, 3, part.offset, part.n), a = share(p.a, 1, part.offset, part.n);
  const std::vector<double> f = share(p.f, 3, part.offset, part.n),
                            t = share(torques_of(p, 280), 3, part.offset, part.n);
  DistributedFmmRpy op(MPI_COMM_WORLD, kViscosity, {.tolerance = 1e-6});
  std::vector<double> u(f.size()), w(f.size());
  expect_collective_error([&] { op.apply(f, t, u, w); }, ErrorCode::invalid_input, "positions not set");
  op.set_positions(x, a);
  std::vector<double> bad_t = t;
  if (world_rank() == last) bad_t[3 * 1 + 2] = std::numeric_limits<double>::quiet_NaN();
  expect_collective_error([&] { op.apply(f, bad_t, u, w); }, ErrorCode::invalid_input,
                          rank_of(last) + "rpyfmm::mpi::DistributedFmmRpy::apply: local torques entry (1, 2) is NaN");
  std::vector<double> bad_f = f;
  if (world_rank() == 0) bad_f[4] = std::numeric_limits<double>::infinity();
  expect_collective_error([&] { op.apply(bad_f, t, u, w); }, ErrorCode::invalid_input,
                          rank_of(0) + "rpyfmm::mpi::DistributedFmmRpy::apply: local forces entry (1, 1) is infinite");
  std::vector<double> short_t = t;
  if (world_rank() == last) short_t.pop_back();
  expect_collective_error([&] { op.apply(f, short_t, u, w); }, ErrorCode::invalid_input,
                          rank_of(last) + "rpyfmm::mpi::DistributedFmmRpy::apply: local torques");
  std::vector<double> long_w(world_rank() == 0 ? w.size() + 3 : w.size());
  expect_collective_error([&] { op.apply(f, t, u, long_w); }, ErrorCode::invalid_input,
                          rank_of(0) + "rpyfmm::mpi::DistributedFmmRpy::apply: local angular velocities");
  EXPECT_NO_THROW(op.apply(f, t, u, w));
}

TEST(MpiDistributedFmmRpy, DifferentOptionsOrViscositiesFailEveryRank) {
  const int last = world_size() - 1;
  const double tolerance = world_rank() == last && world_size() > 1 ? 1e-3 : 1e-6;
  if (world_size() > 1) {
    expect_collective_error([&] { DistributedFmmRpy op(MPI_COMM_WORLD, kViscosity, {.tolerance = tolerance}); },
                            ErrorCode::invalid_argument, "the ranks pass different options");
    const double viscosity = world_rank() == last ? 2.0 : 1.0;
    expect_collective_error([&] { DistributedFmmRpy op(MPI_COMM_WORLD, viscosity); }, ErrorCode::invalid_argument,
                            "the ranks pass different viscosities");
    const SfcCurve curve = world_rank() == last ? SfcCurve::hilbert : SfcCurve::morton;
    expect_collective_error([&] { DistributedFmmRpy op(MPI_COMM_WORLD, kViscosity, {.curve = curve}); },
                            ErrorCode::invalid_argument, "the ranks pass different options");
  }
  const double bad = world_rank() == last ? 0.5 : 1e-6;
  expect_collective_error([&] { DistributedFmmRpy op(MPI_COMM_WORLD, kViscosity, {.tolerance = bad}); },
                          ErrorCode::invalid_argument, rank_of(last) + "rpyfmm::mpi::DistributedFmmRpy");
}
