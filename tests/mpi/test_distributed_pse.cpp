// rpyfmm::mpi::DistributedPseRpy against the serial PseRpy on the concatenation of all ranks'
// particles: the same parameters, and velocities equal to round-off (uniform, clustered in one
// slab, on slab boundaries and box faces, other radii, empty ranks, each split four ways);
// repeated products bit for bit; the split sampler (sample, apply_sqrt, apply_with_noise, also with
// the noise keyed by given global indices) against PseRpy's to round-off; the accuracy against the
// serial operator's single-precision grids at its tolerance; the grand mobility with rotation
// ([U; W] = M [F; T]) against PseRpy's to round-off on the same sets and splits, zero torques against
// the translational product; the split sampler with rotation (apply_sqrt_rotation) against PseRpy's
// to round-off with the same Lanczos iteration count, also with zero rotational noise; and
// collective failure (every rank throws the same message, none hangs) on bad input of one rank; the
// memory limit per rank (a grid refused whole but accepted in slabs, a rank's share over the limit
// refused on every rank).
#include <gtest/gtest.h>
#include <mpi.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <numeric>
#include <string>
#include <vector>

#include "mpi_test_support.hpp"
#include "rpyfmm/mpi/pse_operator.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/random.hpp"

using rpyfmm::ErrorCode;
using rpyfmm::mpi::DistributedPseRpy;
using rpyfmm::rpy::Geometry;
using rpyfmm::rpy::pse::PseOptions;
using rpyfmm::rpy::pse::PseRpy;
using rpyfmm::rpy::pse::WavePrecision;
using namespace rpyfmm_mpi_test;

namespace {

// The bound of the comparison with double-precision grids on both sides. Both operators evaluate
// the same terms by the same code (window weights, pair blocks, c(k) per mode) and differ
// only in the order of additions: grid points summed over particles in another order, FFTW-MPI's
// slab transforms instead of the serial plan, a particle's interpolation summed slab by slab, a
// real-space row over its neighbours in another cell order. Each is a sum of O(10^2 - 10^4) terms
// rounded at 2^-53 relative per addition: a relative 2-norm difference of order 1e-16 - 1e-15,
// measured 6e-17 - 3e-16 on 1-4 ranks (docs/mpi.md); 1e-12 leaves three orders of margin and still
// fails on any missing or doubled term (its size is that of one term, far above 1e-12 here).
constexpr double kRoundOff = 1e-12;

PseOptions double_grids(double tolerance) {
  PseOptions o;
  o.tolerance = tolerance;
  o.wave_precision = WavePrecision::double_precision;
  return o;
}

// Collective: sqrt(sum over ranks |a - b|^2 / sum over ranks |b|^2) of the ranks' shares.
double global_relative_difference(const std::vector<double>& a, const std::vector<double>& b) {
  double local[2] = {0.0, 0.0}, global[2] = {0.0, 0.0};
  for (std::size_t i = 0; i < a.size(); ++i) {
    local[0] += (a[i] - b[i]) * (a[i] - b[i]);
    local[1] += b[i] * b[i];
  }
  MPI_Allreduce(local, global, 2, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  return std::sqrt(global[0] / global[1]);
}

struct Shares {
  std::size_t offset = 0, n = 0;
};

Shares shares_of(std::size_t total, Split split) {
  const Partition part = partition_of(total, split);
  return {part.offset, part.n};
}

// M F of the serial operator on the whole set (every rank computes it: the sets are small).
std::vector<double> serial_velocities(const Particles& p, const Geometry& box, const PseOptions& options,
                                      rpyfmm::rpy::pse::PseParameters* parameters = nullptr) {
  PseRpy serial(box, kViscosity, options);
  serial.set_positions(p.x, p.a[0]);
  std::vector<double> u(3 * p.size());
  serial.apply(p.f, u);
  if (parameters != nullptr) *parameters = serial.parameters();
  return u;
}

// Distributes `p` by `split`, applies M on the shares and returns the relative 2-norm difference
// from the serial operator's velocities of the whole set; checks the parameters, the sizes and that
// a second product gives the same bits.
double difference_from_serial(const Particles& p, const Geometry& box, const PseOptions& options, Split split,
                              const std::vector<double>& u_serial, const rpyfmm::rpy::pse::PseParameters& serial_p) {
  const Shares s = shares_of(p.size(), split);
  DistributedPseRpy op(MPI_COMM_WORLD, box, kViscosity, options);
  op.set_positions(share(p.x, 3, s.offset, s.n), share(p.a, 1, s.offset, s.n));
  EXPECT_EQ(op.global_size(), p.size());
  EXPECT_EQ(op.local_size(), s.n);
  EXPECT_EQ(op.offset(), s.offset);
  const auto& q = op.parameters();
  EXPECT_EQ(q.xi, serial_p.xi);
  EXPECT_EQ(q.r_cut, serial_p.r_cut);
  EXPECT_EQ(q.grid, serial_p.grid);
  EXPECT_EQ(q.support, serial_p.support);
  EXPECT_EQ(q.sigma, serial_p.sigma);
  const std::vector<double> f = share(p.f, 3, s.offset, s.n);
  std::vector<double> u(3 * s.n, std::numeric_limits<double>::quiet_NaN()), again(u);
  op.apply(f, u);
  op.apply(f, again);
  EXPECT_EQ(bitwise_mismatches(u, again), 0U) << "a repeated product differs";
  // On several ranks the exchanges run: windows cross to other ranks' slabs (every split), and
  // with the even split of 100 or more particles every rank has a halo from its neighbours.
  const auto& c = op.exchange_counts();
  const unsigned long local[2] = {c.wave_sent + c.wave_received, c.halo_received};
  unsigned long global[2] = {0, 0};
  MPI_Allreduce(local, global, 2, MPI_UNSIGNED_LONG, MPI_SUM, MPI_COMM_WORLD);
  if (world_size() > 1 && p.size() >= 100) {
    EXPECT_GT(global[0], 0UL);
    if (split == Split::even) {
      EXPECT_GT(global[1], 0UL);
    }
  }
  return global_relative_difference(u, share(u_serial, 3, s.offset, s.n));
}

void expect_round_off(const Particles& p, const Geometry& box, const PseOptions& options) {
  rpyfmm::rpy::pse::PseParameters serial_p;
  const std::vector<double> u_serial = serial_velocities(p, box, options, &serial_p);
  for (const Split split : kSplits) {
    const double d = difference_from_serial(p, box, options, split, u_serial, serial_p);
    EXPECT_LE(d, kRoundOff) << "split " << static_cast<int>(split);
    if (world_rank() == 0)
      std::printf("  [pse] N = %zu, split %d: relative difference %.2e\n", p.size(), static_cast<int>(split), d);
  }
}

Particles uniform_set(std::size_t n, const std::array<double, 3>& box, double a, std::uint64_t seed) {
  Particles p = uniform_particles(n, 1.0, a, a, seed);
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t d = 0; d < 3; ++d) p.x[3 * i + d] *= box[d];
  return p;
}

// Torques in [-1, 1]^3 per particle (the same on every rank for one seed).
std::vector<double> torques_of(std::size_t n, std::uint64_t seed) {
  return uniform_particles(n, 1.0, 1.0, 1.0, seed).f;
}

// The grand product [U; W] = M [F; T] of one operator (U and W of 3 n entries each).
struct Grand {
  std::vector<double> u, w;
};

// PseRpy's grand product on the whole set (every rank computes it: the sets are small).
Grand serial_grand(const Particles& p, const std::vector<double>& t, const Geometry& box, const PseOptions& options) {
  PseRpy serial(box, kViscosity, options);
  serial.set_positions(p.x, p.a[0]);
  Grand g{std::vector<double>(3 * p.size()), std::vector<double>(3 * p.size())};
  serial.apply(p.f, t, g.u, g.w);
  return g;
}

// Distributes `p` and `t` by every split, applies the grand mobility on the shares and expects U
// and W each within kRoundOff of PseRpy's (relative 2-norm over all ranks), and a repeated product
// with the same bits.
void expect_grand_round_off(const Particles& p, const Geometry& box, const PseOptions& options, std::uint64_t seed) {
  const std::vector<double> t = torques_of(p.size(), seed);
  const Grand serial = serial_grand(p, t, box, options);
  for (const Split split : kSplits) {
    const Shares s = shares_of(p.size(), split);
    DistributedPseRpy op(MPI_COMM_WORLD, box, kViscosity, options);
    ASSERT_TRUE(op.supports_rotation());
    op.set_positions(share(p.x, 3, s.offset, s.n), share(p.a, 1, s.offset, s.n));
    const std::vector<double> f = share(p.f, 3, s.offset, s.n), ts = share(t, 3, s.offset, s.n);
    std::vector<double> u(3 * s.n, std::numeric_limits<double>::quiet_NaN()), w(u), u2(u), w2(u);
    op.apply(f, ts, u, w);
    op.apply(f, ts, u2, w2);
    EXPECT_EQ(bitwise_mismatches(u, u2), 0U) << "a repeated product differs in U";
    EXPECT_EQ(bitwise_mismatches(w, w2), 0U) << "a repeated product differs in W";
    const double du = global_relative_difference(u, share(serial.u, 3, s.offset, s.n));
    const double dw = global_relative_difference(w, share(serial.w, 3, s.offset, s.n));
    EXPECT_LE(du, kRoundOff) << "U, split " << static_cast<int>(split);
    EXPECT_LE(dw, kRoundOff) << "W, split " << static_cast<int>(split);
    if (world_rank() == 0) {
      std::printf("  [pse rotation] N = %zu, split %d: relative difference U %.2e, W %.2e\n", p.size(),
                  static_cast<int>(split), du, dw);
    }
  }
}

// The split sampler with rotation on one operator: [w_t; w_r] for the noise [z_t; z_r] and its report.
struct GrandSample {
  Grand w;
  rpyfmm::rpy::SqrtReport report;
};

// PseRpy::apply_sqrt_rotation (split) on the whole set (every rank computes it: the sets are small).
GrandSample serial_grand_sample(const Particles& p, const std::vector<double>& zt, const std::vector<double>& zr,
                                const Geometry& box, const PseOptions& options) {
  PseRpy serial(box, kViscosity, options);
  serial.set_positions(p.x, p.a[0]);
  GrandSample g{{std::vector<double>(3 * p.size()), std::vector<double>(3 * p.size())}, {}};
  rpyfmm::rpy::SqrtOptions split;
  split.method = rpyfmm::rpy::SqrtMethod::split;
  g.report = serial.apply_sqrt_rotation(zt, zr, g.w.u, g.w.w, split);
  return g;
}

// Distributes `p` and the noise [z_t; z_r] (z_r zero where `zero_rotation`) by every split, samples
// with apply_sqrt_rotation on the shares and expects w_t and w_r each within kRoundOff of PseRpy's
// (relative 2-norm over all ranks), the serial Lanczos iteration count, and a repeated sample with
// the same bits. The bound is kRoundOff's, for its reasons: the same Lanczos iteration on S M_r S
// (products and inner products equal to round-off, so the same iterations), the same wave field
// (z2 keyed by the hash of the whole z, drawn mode by mode), scaled per mode by the same code.
// The sampler's covariance (E[w w^T] = M with rotation) is tested on the serial sampler that this
// one equals: PseSampler.RotationSplitSampleCovarianceEqualsGrandMobility
// (tests/pse/test_pse_statistics.cpp).
void expect_grand_sample_round_off(const Particles& p, const Geometry& box, const PseOptions& options,
                                   std::uint64_t seed, bool zero_rotation) {
  std::vector<double> zt(3 * p.size()), zr(3 * p.size(), 0.0);
  rpyfmm::rpy::fill_normal(zt, seed, 1);
  if (!zero_rotation) rpyfmm::rpy::fill_normal(zr, seed, 2);
  const GrandSample serial = serial_grand_sample(p, zt, zr, box, options);
  for (const Split split : kSplits) {
    const Shares s = shares_of(p.size(), split);
    DistributedPseRpy op(MPI_COMM_WORLD, box, kViscosity, options);
    op.set_positions(share(p.x, 3, s.offset, s.n), share(p.a, 1, s.offset, s.n));
    const std::vector<double> zts = share(zt, 3, s.offset, s.n), zrs = share(zr, 3, s.offset, s.n);
    std::vector<double> wt(3 * s.n, std::numeric_limits<double>::quiet_NaN()), wr(wt), wt2(wt), wr2(wt);
    const rpyfmm::rpy::SqrtReport report = op.apply_sqrt_rotation(zts, zrs, wt, wr);
    op.apply_sqrt_rotation(zts, zrs, wt2, wr2);
    EXPECT_EQ(bitwise_mismatches(wt, wt2), 0U) << "a repeated sample differs in w_t";
    EXPECT_EQ(bitwise_mismatches(wr, wr2), 0U) << "a repeated sample differs in w_r";
    EXPECT_EQ(report.method, rpyfmm::rpy::SqrtMethod::split);
    EXPECT_EQ(report.iterations, serial.report.iterations);
    EXPECT_EQ(report.operator_applications, serial.report.operator_applications);
    const double dt = global_relative_difference(wt, share(serial.w.u, 3, s.offset, s.n));
    const double dr = global_relative_difference(wr, share(serial.w.w, 3, s.offset, s.n));
    EXPECT_LE(dt, kRoundOff) << "w_t, split " << static_cast<int>(split);
    EXPECT_LE(dr, kRoundOff) << "w_r, split " << static_cast<int>(split);
    if (world_rank() == 0) {
      std::printf("  [pse rotation sampler] N = %zu%s, split %d: %d Lanczos iterations; w_t %.2e, w_r %.2e\n", p.size(),
                  zero_rotation ? " (z_r = 0)" : "", static_cast<int>(split), report.iterations, dt, dr);
    }
  }
}

}  // namespace

TEST(MpiDistributedPse, UniformSuspensionEqualsSerialToRoundOff) {
  const Geometry box = Geometry::periodic(16.0);
  expect_round_off(uniform_set(300, box.box(), 1.0, 11), box, double_grids(1e-6));
}

TEST(MpiDistributedPse, ClusterInOneSlabAndOtherRadiusEqualToSerial) {
  // Every particle within x in [1, 2.5] of a box 24 x 16 x 20: all in the lowest rank's slab (and
  // windows wrapping through x = 0 into the last rank's), none elsewhere; radius 0.6.
  const Geometry box = Geometry::periodic(24.0, 16.0, 20.0);
  Particles p = uniform_set(200, {1.5, 16.0, 20.0}, 0.6, 12);
  for (std::size_t i = 0; i < p.size(); ++i) p.x[3 * i] += 1.0;
  expect_round_off(p, box, double_grids(1e-5));
}

TEST(MpiDistributedPse, SlabBoundariesAndBoxFacesEqualToSerial) {
  // A particle on every x plane of the grid (so on every slab boundary for any number of ranks),
  // and on the box faces: 0, L, -L, 2L, L - ulp, -0 and far outside (wrapped as PseRpy wraps).
  const double L = 14.0;
  const Geometry box = Geometry::periodic(L);
  const PseOptions options = double_grids(1e-4);
  Particles p = uniform_set(120, box.box(), 1.3, 13);
  PseRpy probe(box, kViscosity, options);
  probe.set_positions(p.x, 1.3);
  const auto& q = probe.parameters();
  for (int g = 0; g < q.grid[0]; ++g) {
    p.x[3 * static_cast<std::size_t>(g)] = g * q.spacing[0];
  }
  const double faces[] = {0.0, L, -L, 2.0 * L, std::nextafter(L, 0.0), -0.0, -1e3 * L + 0.25};
  std::size_t i = static_cast<std::size_t>(q.grid[0]);
  for (const double v : faces) {
    p.x[3 * i] = v;
    p.x[3 * i + 1] = faces[(i + 1) % 7];
    p.x[3 * i + 2] = faces[(i + 3) % 7];
    ++i;
  }
  expect_round_off(p, box, options);
}

TEST(MpiDistributedPse, EmptyRanksAndMoreRanksThanParticles) {
  const Geometry box = Geometry::periodic(10.0);
  expect_round_off(uniform_set(2, box.box(), 1.0, 14), box, double_grids(1e-4));
  expect_round_off(uniform_set(1, box.box(), 1.0, 15), box, double_grids(1e-4));
}

TEST(MpiDistributedPse, FewGridPlanesLeaveRanksWithoutSlab) {
  // A grid of 6 x 8 x 10 points (override): FFTW-MPI gives slabs of 2 planes on 3 and 4 ranks
  // (the fourth rank owns none), 3 on 2 ranks; windows of P_x points then span several slabs.
  const Geometry box = Geometry::periodic(10.0, 12.0, 14.0);
  PseOptions options = double_grids(1e-3);
  options.grid = {6, 8, 10};
  options.support = 4;
  options.xi = 1.2;
  expect_round_off(uniform_set(80, box.box(), 0.5, 18), box, options);
}

TEST(MpiDistributedPse, AccuracyAgainstSerialSinglePrecisionGrids) {
  // At tolerance 1e-3 the serial operator takes float grids (WavePrecision::automatic), the
  // distributed one double grids: they differ by the serial grids' float round-off, ~1e-7
  // relative (tests/pse/test_pse_precision.cpp), which the serial design keeps 100 x below the
  // tolerance (kSingleWaveTolerance = 1e-5): that is the bound tested.
  const Geometry box = Geometry::periodic(16.0);
  const Particles p = uniform_set(300, box.box(), 1.0, 16);
  PseOptions options;
  options.tolerance = 1e-3;
  rpyfmm::rpy::pse::PseParameters serial_p;
  const std::vector<double> u_single = serial_velocities(p, box, options, &serial_p);
  ASSERT_TRUE(serial_p.wave_single);
  const double d = difference_from_serial(p, box, options, Split::even, u_single, serial_p);
  EXPECT_LE(d, rpyfmm::rpy::pse::kSingleWaveTolerance);
  if (world_rank() == 0) std::printf("  [pse] against float grids at tolerance 1e-3: %.2e\n", d);
}

TEST(MpiDistributedPse, SplitSamplerEqualsSerialToRoundOff) {
  // PseRpy::sample on the whole set against DistributedPseRpy::sample on the shares: the same noise
  // (z1 by global index, z2 by mode), the same Lanczos iteration on M_r (its products and inner
  // products equal to round-off, so the same number of iterations) and the same wave-space field;
  // the bound is kRoundOff's, for the same reasons.
  const Geometry box = Geometry::periodic(16.0);
  const Particles p = uniform_set(300, box.box(), 1.0, 19);
  const PseOptions options = double_grids(1e-6);
  PseRpy serial(box, kViscosity, options);
  serial.set_positions(p.x, 1.0);
  std::vector<double> w_serial(3 * p.size()), z(3 * p.size()), wz_serial(3 * p.size());
  const rpyfmm::rpy::SqrtReport serial_report = serial.sample(7, 3, w_serial);
  rpyfmm::rpy::fill_normal(z, 5, 2);
  serial.apply_sqrt(z, wz_serial);
  std::vector<double> un_serial(3 * p.size());
  serial.apply_with_noise(p.f, 0.8, 7, 3, un_serial);
  for (const Split split : kSplits) {
    const Shares s = shares_of(p.size(), split);
    DistributedPseRpy op(MPI_COMM_WORLD, box, kViscosity, options);
    op.set_positions(share(p.x, 3, s.offset, s.n), 1.0);
    std::vector<double> w(3 * s.n, std::numeric_limits<double>::quiet_NaN()), again(w);
    const rpyfmm::rpy::SqrtReport report = op.sample(7, 3, w);
    op.sample(7, 3, again);
    EXPECT_EQ(bitwise_mismatches(w, again), 0U) << "a repeated sample differs";
    EXPECT_EQ(report.iterations, serial_report.iterations);
    EXPECT_EQ(report.method, rpyfmm::rpy::SqrtMethod::split);
    const double d = global_relative_difference(w, share(w_serial, 3, s.offset, s.n));
    EXPECT_LE(d, kRoundOff) << "split " << static_cast<int>(split);
    // apply_sqrt(z): z as z1, z2 keyed by the hash of the whole z (chained over the ranks).
    std::vector<double> wz(3 * s.n);
    op.apply_sqrt(share(z, 3, s.offset, s.n), wz);
    const double dz = global_relative_difference(wz, share(wz_serial, 3, s.offset, s.n));
    EXPECT_LE(dz, kRoundOff) << "apply_sqrt, split " << static_cast<int>(split);
    // apply_with_noise: M F + 0.8 M^{1/2} z with the noise of sample(7, 3).
    std::vector<double> un(3 * s.n);
    op.apply_with_noise(share(p.f, 3, s.offset, s.n), 0.8, 7, 3, un);
    const double dn = global_relative_difference(un, share(un_serial, 3, s.offset, s.n));
    EXPECT_LE(dn, kRoundOff) << "apply_with_noise, split " << static_cast<int>(split);
    if (world_rank() == 0) {
      std::printf("  [pse] split %d: %d Lanczos iterations; sample %.2e, apply_sqrt %.2e, apply_with_noise %.2e\n",
                  static_cast<int>(split), report.iterations, d, dz, dn);
    }
  }
}

TEST(MpiDistributedPse, FusedNoiseKeyedByGivenGlobalIndicesEqualsSerialInThatOrder) {
  // The ranks hold the particles in input order but number them backwards (global index N - 1 - k
  // for the k-th of the concatenation): apply_with_noise with those indices equals PseRpy's on the
  // whole set in the backward order, to kRoundOff (the Lanczos iteration on M_r of a permuted set:
  // the same Krylov space, its sums in another order).
  const Geometry box = Geometry::periodic(16.0);
  const Particles p = uniform_set(300, box.box(), 1.0, 23);
  const PseOptions options = double_grids(1e-6);
  const std::size_t n = p.size();
  std::vector<double> x_back(3 * n), f_back(3 * n), u_back(3 * n);
  for (std::size_t k = 0; k < n; ++k)
    for (std::size_t c = 0; c < 3; ++c) {
      x_back[3 * (n - 1 - k) + c] = p.x[3 * k + c];
      f_back[3 * (n - 1 - k) + c] = p.f[3 * k + c];
    }
  PseRpy serial(box, kViscosity, options);
  serial.set_positions(x_back, 1.0);
  serial.apply_with_noise(f_back, 0.8, 7, 3, u_back);
  for (const Split split : kSplits) {
    const Shares s = shares_of(n, split);
    DistributedPseRpy op(MPI_COMM_WORLD, box, kViscosity, options);
    op.set_positions(share(p.x, 3, s.offset, s.n), 1.0);
    std::vector<std::uint64_t> indices(s.n);
    std::vector<double> expected(3 * s.n), u(3 * s.n);
    for (std::size_t k = 0; k < s.n; ++k) {
      indices[k] = n - 1 - (s.offset + k);
      for (std::size_t c = 0; c < 3; ++c) expected[3 * k + c] = u_back[3 * indices[k] + c];
    }
    op.apply_with_noise(share(p.f, 3, s.offset, s.n), 0.8, 7, 3, indices, u);
    const double d = global_relative_difference(u, expected);
    EXPECT_LE(d, kRoundOff) << "split " << static_cast<int>(split);
    if (world_rank() == 0)
      std::printf("  [pse] split %d, indices backwards: apply_with_noise %.2e\n", static_cast<int>(split), d);
  }
}

// The grand mobility with rotation against PseRpy's on the whole set: the same terms by the same
// code (window weights, scale_rotation_mode per mode, the rotational table over the same pairs),
// added in another order, as for U = M F; so the bound is kRoundOff, for the reasons given there.
TEST(MpiDistributedPse, GrandMobilityEqualsSerialToRoundOff) {
  const Geometry box = Geometry::periodic(16.0);
  expect_grand_round_off(uniform_set(300, box.box(), 1.0, 31), box, double_grids(1e-6), 32);
}

TEST(MpiDistributedPse, GrandMobilityClusterInOneSlabAndOtherRadius) {
  // As ClusterInOneSlabAndOtherRadiusEqualToSerial: all particles in the lowest rank's slab, radius
  // 0.6 (the torque load scale and the rotational table depend on the radius).
  const Geometry box = Geometry::periodic(24.0, 16.0, 20.0);
  Particles p = uniform_set(200, {1.5, 16.0, 20.0}, 0.6, 33);
  for (std::size_t i = 0; i < p.size(); ++i) p.x[3 * i] += 1.0;
  expect_grand_round_off(p, box, double_grids(1e-5), 34);
}

TEST(MpiDistributedPse, GrandMobilityFewGridPlanesAndEmptyRanks) {
  // Ranks without a slab (6 x-planes over 4 ranks), windows spanning several slabs; then 2 and 1
  // particles (most ranks empty).
  const Geometry box = Geometry::periodic(10.0, 12.0, 14.0);
  PseOptions options = double_grids(1e-3);
  options.grid = {6, 8, 10};
  options.support = 4;
  options.xi = 1.2;
  expect_grand_round_off(uniform_set(80, box.box(), 0.5, 35), box, options, 36);
  const Geometry cube = Geometry::periodic(10.0);
  expect_grand_round_off(uniform_set(2, cube.box(), 1.0, 37), cube, double_grids(1e-4), 38);
  expect_grand_round_off(uniform_set(1, cube.box(), 1.0, 39), cube, double_grids(1e-4), 40);
}

TEST(MpiDistributedPse, ZeroTorquesGiveTheTranslationalVelocities) {
  // With T = 0 the grand product's U is M F, but formed otherwise than by apply(F, U): each mode
  // scaled by g(k) sinc sinc instead of c(k) = sinc^2 g(k), the rotational blocks adding zeros. So
  // it equals the force-only product to round-off (kRoundOff; PseRpy's own test of the same claim
  // uses 1e-13), not bit for bit. The force-only product itself is bit for bit the same before and
  // after a product with torques (the torque slabs and the rotational table leave it alone).
  const Geometry box = Geometry::periodic(16.0);
  const Particles p = uniform_set(300, box.box(), 1.0, 41);
  const PseOptions options = double_grids(1e-6);
  for (const Split split : {Split::even, Split::first_empty}) {
    const Shares s = shares_of(p.size(), split);
    DistributedPseRpy op(MPI_COMM_WORLD, box, kViscosity, options);
    op.set_positions(share(p.x, 3, s.offset, s.n), 1.0);
    const std::vector<double> f = share(p.f, 3, s.offset, s.n), zero(3 * s.n, 0.0);
    std::vector<double> before(3 * s.n), after(3 * s.n), u(3 * s.n), w(3 * s.n);
    op.apply(f, before);
    op.apply(f, zero, u, w);
    op.apply(f, after);
    EXPECT_EQ(bitwise_mismatches(before, after), 0U) << "the force-only product changed after one with torques";
    const double d = global_relative_difference(u, before);
    EXPECT_LE(d, kRoundOff) << "split " << static_cast<int>(split);
    if (world_rank() == 0)
      std::printf("  [pse rotation] split %d: zero torques against U = M F %.2e\n", static_cast<int>(split), d);
  }
}

TEST(MpiDistributedPse, GrandSplitSamplerKeyedByGivenGlobalIndicesEqualsSerialInThatOrder) {
  // The ranks hold the particles in input order but number them backwards (global index N - 1 - k
  // for the k-th of the concatenation): apply_sqrt_rotation with those indices keys the wave noise
  // by the hash of [z_t; z_r] in that order, so it equals PseRpy::apply_sqrt_rotation on the whole
  // set in the backward order to kRoundOff (the Lanczos iteration on S M_r S of a permuted set: the
  // same Krylov space, its sums in another order). The overload without indices hashes the rank
  // order instead and draws another wave field, far from this one. A repeated index fails every
  // rank.
  const Geometry box = Geometry::periodic(16.0);
  const Particles p = uniform_set(300, box.box(), 1.0, 61);
  const std::size_t n = p.size();
  const std::vector<double> zt = torques_of(n, 62), zr = torques_of(n, 63);
  Particles back = p;
  std::vector<double> zt_back(3 * n), zr_back(3 * n);
  for (std::size_t k = 0; k < n; ++k)
    for (std::size_t c = 0; c < 3; ++c) {
      back.x[3 * (n - 1 - k) + c] = p.x[3 * k + c];
      zt_back[3 * (n - 1 - k) + c] = zt[3 * k + c];
      zr_back[3 * (n - 1 - k) + c] = zr[3 * k + c];
    }
  const GrandSample serial = serial_grand_sample(back, zt_back, zr_back, box, double_grids(1e-6));
  for (const Split split : kSplits) {
    const Shares s = shares_of(n, split);
    DistributedPseRpy op(MPI_COMM_WORLD, box, kViscosity, double_grids(1e-6));
    op.set_positions(share(p.x, 3, s.offset, s.n), 1.0);
    std::vector<std::uint64_t> indices(s.n);
    std::vector<double> expected_t(3 * s.n), expected_r(3 * s.n), wt(3 * s.n), wr(3 * s.n), wt_rank(3 * s.n),
        wr_rank(3 * s.n);
    for (std::size_t k = 0; k < s.n; ++k) {
      indices[k] = n - 1 - (s.offset + k);
      for (std::size_t c = 0; c < 3; ++c) {
        expected_t[3 * k + c] = serial.w.u[3 * indices[k] + c];
        expected_r[3 * k + c] = serial.w.w[3 * indices[k] + c];
      }
    }
    const std::vector<double> zts = share(zt, 3, s.offset, s.n), zrs = share(zr, 3, s.offset, s.n);
    const rpyfmm::rpy::SqrtReport report = op.apply_sqrt_rotation(zts, zrs, indices, wt, wr);
    op.apply_sqrt_rotation(zts, zrs, wt_rank, wr_rank);
    const double dt = global_relative_difference(wt, expected_t), dr = global_relative_difference(wr, expected_r);
    EXPECT_LE(dt, kRoundOff) << "split " << static_cast<int>(split);
    EXPECT_LE(dr, kRoundOff) << "split " << static_cast<int>(split);
    EXPECT_EQ(report.iterations, serial.report.iterations);
    EXPECT_GT(global_relative_difference(wt_rank, expected_t), 1e-3) << "the rank order keys another wave field";
    if (split == Split::even) {  // every rank holds about n / P >= 75 particles: repeat one on the last
      std::vector<std::uint64_t> repeated = indices;
      if (world_rank() == world_size() - 1) repeated[0] = repeated[1];
      expect_collective_error([&] { op.apply_sqrt_rotation(zts, zrs, repeated, wt, wr); }, ErrorCode::invalid_input,
                              "is given more than once");
    }
    if (world_rank() == 0)
      std::printf("  [pse] split %d, indices backwards: apply_sqrt_rotation %.2e, %.2e\n", static_cast<int>(split), dt,
                  dr);
  }
}

TEST(MpiDistributedPse, RotationBadInputOnOneRankFailsEveryRank) {
  const Geometry box = Geometry::periodic(12.0);
  const Particles p = uniform_set(60, box.box(), 1.0, 42);
  const Shares s = shares_of(p.size(), Split::even);
  const int last = world_size() - 1;
  DistributedPseRpy op(MPI_COMM_WORLD, box, kViscosity, double_grids(1e-4));
  std::vector<double> x = share(p.x, 3, s.offset, s.n), f = share(p.f, 3, s.offset, s.n);
  std::vector<double> t = share(torques_of(p.size(), 43), 3, s.offset, s.n), u(3 * s.n), w(3 * s.n);
  // The split sampler with rotation's noise [z_t; z_r] and output [w_t; w_r] of this rank's share.
  std::vector<double> zt(3 * p.size()), zr(3 * p.size());
  rpyfmm::rpy::fill_normal(zt, 62, 1);
  rpyfmm::rpy::fill_normal(zr, 62, 2);
  const std::vector<double> zts = share(zt, 3, s.offset, s.n), zrs = share(zr, 3, s.offset, s.n);
  std::vector<double> wt(3 * s.n), wr(3 * s.n);
  expect_collective_error([&] { op.apply(f, t, u, w); }, ErrorCode::invalid_input, "positions not set");
  expect_collective_error([&] { op.apply_sqrt_rotation(zts, zrs, wt, wr); }, ErrorCode::invalid_input,
                          "positions not set");
  op.set_positions(x, 1.0);
  // Every rank holds particles in the even split of 60 over 1-4 ranks.
  std::vector<double> short_t(t.begin(), t.end() - (world_rank() == last ? 1 : 0));
  expect_collective_error([&] { op.apply(f, short_t, u, w); }, ErrorCode::invalid_input, "local torques");
  std::vector<double> long_w(w.size() + (world_rank() == 0 ? 3 : 0));
  expect_collective_error([&] { op.apply(f, t, u, long_w); }, ErrorCode::invalid_input, "local angular velocities");
  std::vector<double> short_u(u.begin(), u.end() - (world_rank() == last ? 3 : 0));
  expect_collective_error([&] { op.apply(f, t, short_u, w); }, ErrorCode::invalid_input, "local velocities");
  std::vector<double> nan_t = t;
  if (world_rank() == last) nan_t[4] = std::numeric_limits<double>::quiet_NaN();
  expect_collective_error([&] { op.apply(f, nan_t, u, w); }, ErrorCode::invalid_input, "NaN");
  std::vector<double> inf_f = f;
  if (world_rank() == 0) inf_f[2] = std::numeric_limits<double>::infinity();
  expect_collective_error([&] { op.apply(inf_f, t, u, w); }, ErrorCode::invalid_input, "local forces");
  // apply_sqrt_rotation: sizes of noise and output, NaN/Inf in either noise, another method or the
  // block preconditioner on one rank.
  const auto longer_on = [](const std::vector<double>& v, int rank) {
    std::vector<double> r(v);
    if (world_rank() == rank) r.resize(r.size() + 3);
    return r;
  };
  const std::vector<double> bad_zt = longer_on(zts, 0), bad_zr = longer_on(zrs, last);
  std::vector<double> bad_wt = longer_on(wt, last), bad_wr = longer_on(wr, 0);
  const char* const noise_t = "local translational noise";
  expect_collective_error([&] { op.apply_sqrt_rotation(bad_zt, zrs, wt, wr); }, ErrorCode::invalid_input, noise_t);
  expect_collective_error([&] { op.apply_sqrt_rotation(zts, bad_zr, wt, wr); }, ErrorCode::invalid_input,
                          "local rotational noise");
  expect_collective_error([&] { op.apply_sqrt_rotation(zts, zrs, bad_wt, wr); }, ErrorCode::invalid_input,
                          "local translational output");
  expect_collective_error([&] { op.apply_sqrt_rotation(zts, zrs, wt, bad_wr); }, ErrorCode::invalid_input,
                          "local rotational output");
  std::vector<double> nan_zr = zrs;
  if (world_rank() == last) nan_zr[1] = std::numeric_limits<double>::quiet_NaN();
  expect_collective_error([&] { op.apply_sqrt_rotation(zts, nan_zr, wt, wr); }, ErrorCode::invalid_input, "NaN");
  std::vector<double> inf_zt = zts;
  if (world_rank() == 0) inf_zt[2] = -std::numeric_limits<double>::infinity();
  expect_collective_error([&] { op.apply_sqrt_rotation(inf_zt, zrs, wt, wr); }, ErrorCode::invalid_input, noise_t);
  rpyfmm::rpy::SqrtOptions other;
  other.method = world_rank() == last ? rpyfmm::rpy::SqrtMethod::lanczos : rpyfmm::rpy::SqrtMethod::split;
  expect_collective_error([&] { op.apply_sqrt_rotation(zts, zrs, wt, wr, other); }, ErrorCode::not_supported,
                          "not offered across ranks");
  rpyfmm::rpy::SqrtOptions block;
  if (world_rank() == 0) block.preconditioner = rpyfmm::rpy::SqrtPreconditioner::block;
  expect_collective_error([&] { op.apply_sqrt_rotation(zts, zrs, wt, wr, block); }, ErrorCode::not_supported,
                          "block preconditioner");
  // Usable afterwards, and equal to the serial operator and sampler.
  op.apply(f, t, u, w);
  const Grand serial = serial_grand(p, torques_of(p.size(), 43), box, double_grids(1e-4));
  EXPECT_LE(global_relative_difference(u, share(serial.u, 3, s.offset, s.n)), kRoundOff);
  EXPECT_LE(global_relative_difference(w, share(serial.w, 3, s.offset, s.n)), kRoundOff);
  op.apply_sqrt_rotation(zts, zrs, wt, wr);
  const GrandSample sampled = serial_grand_sample(p, zt, zr, box, double_grids(1e-4));
  EXPECT_LE(global_relative_difference(wt, share(sampled.w.u, 3, s.offset, s.n)), kRoundOff);
  EXPECT_LE(global_relative_difference(wr, share(sampled.w.w, 3, s.offset, s.n)), kRoundOff);
}

TEST(MpiDistributedPse, GrandSplitSamplerEqualsSerialToRoundOff) {
  const Geometry box = Geometry::periodic(16.0);
  expect_grand_sample_round_off(uniform_set(300, box.box(), 1.0, 51), box, double_grids(1e-6), 52, false);
}

TEST(MpiDistributedPse, GrandSplitSamplerZeroRotationalNoise) {
  // z_r = 0: w_r is not zero (the real part's coupling blocks and the wave noise's rotational
  // part), and the hash of [z_t; 0] keys the wave field, as in PseRpy.
  const Geometry box = Geometry::periodic(16.0);
  expect_grand_sample_round_off(uniform_set(300, box.box(), 1.0, 53), box, double_grids(1e-6), 54, true);
}

TEST(MpiDistributedPse, GrandSplitSamplerClusterFewPlanesAndEmptyRanks) {
  // All particles in the lowest rank's slab with radius 0.6 (S = diag(I, a I) with a != 1); ranks
  // without a slab (6 x-planes over 4 ranks); 2 particles (most ranks empty, the hash chain
  // skipping them).
  const Geometry slab_box = Geometry::periodic(24.0, 16.0, 20.0);
  Particles p = uniform_set(200, {1.5, 16.0, 20.0}, 0.6, 55);
  for (std::size_t i = 0; i < p.size(); ++i) p.x[3 * i] += 1.0;
  expect_grand_sample_round_off(p, slab_box, double_grids(1e-5), 56, false);
  const Geometry box = Geometry::periodic(10.0, 12.0, 14.0);
  PseOptions options = double_grids(1e-3);
  options.grid = {6, 8, 10};
  options.support = 4;
  options.xi = 1.2;
  expect_grand_sample_round_off(uniform_set(80, box.box(), 0.5, 57), box, options, 58, false);
  const Geometry cube = Geometry::periodic(10.0);
  expect_grand_sample_round_off(uniform_set(2, cube.box(), 1.0, 59), cube, double_grids(1e-4), 60, false);
}

// The memory tests' configuration: box 12, xi 1.2, grid 24^3 and support 12 or 16 (overrides, so
// that the bytes below follow from the formulas of docs/mpi.md, "Distributed PSE", Limits), double
// grids. Per rank: 56 bytes per mode of its slab (three in-place components of 16 bytes, c(k) of 8;
// 24 x 24 x 13 modes in all, 419328 bytes), plus 8 (3 P + 8) bytes per particle of the rank.
// PseRpy's estimate of the whole grid adds separate real grids: 3 (8 x 24^3 + 64 x 25) = 336576
// bytes more, plus 8 (3 P + 8) per particle of the set.
PseOptions memory_test_options(int support, std::size_t max_memory_bytes) {
  PseOptions o = double_grids(1e-4);
  o.xi = 1.2;
  o.grid = {24, 24, 24};
  o.support = support;
  o.max_memory_bytes = max_memory_bytes;
  return o;
}

constexpr std::size_t kUnlimited = std::numeric_limits<std::size_t>::max();
constexpr double kSlabBytesPerMode = 56.0;
constexpr double kGridModes = 24.0 * 24.0 * 13.0;

TEST(MpiDistributedPse, SlabsWithinTheMemoryLimitWhereTheWholeGridIsNot) {
  // Support 12 (352 bytes per particle), 60 particles, limit 600000 bytes. The whole grid by
  // PseRpy's estimate needs 755904 + 352 x 60 = 777024 bytes > 600000: PseRpy refuses it, and so
  // does one rank. On P >= 2 ranks a rank's slab holds at most 12 of the 24 planes (FFTW-MPI's
  // blocks of ceil(24 / P) planes): at most 12 x 24 x 13 x 56 + 352 x 60 = 230784 bytes < 600000,
  // whatever the split; and the choice's budget for the whole grid, P x 600000 >= 1.2e6, holds it.
  const Geometry box = Geometry::periodic(12.0);
  const Particles p = uniform_set(60, box.box(), 0.5, 21);
  const PseOptions limited = memory_test_options(12, 600000);
  PseRpy serial_limited(box, kViscosity, limited);
  try {
    serial_limited.set_positions(p.x, p.a[0]);
    ADD_FAILURE() << "PseRpy accepted the whole grid within 600000 bytes";
  } catch (const rpyfmm::Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::out_of_memory) << e.what();
  }
  if (world_size() == 1) {
    expect_collective_error(
        [&] {
          DistributedPseRpy op(MPI_COMM_WORLD, box, kViscosity, limited);
          op.set_positions(p.x, p.a[0]);
        },
        ErrorCode::out_of_memory, "max_memory_bytes");
    return;
  }
  rpyfmm::rpy::pse::PseParameters serial_p;
  const std::vector<double> u_serial = serial_velocities(p, box, memory_test_options(12, kUnlimited), &serial_p);
  for (const Split split : kSplits) {
    // The same parameters as the unlimited PseRpy and its velocities to round-off (kRoundOff).
    const double d = difference_from_serial(p, box, limited, split, u_serial, serial_p);
    EXPECT_LE(d, kRoundOff) << "split " << static_cast<int>(split);
    const Shares s = shares_of(p.size(), split);
    DistributedPseRpy op(MPI_COMM_WORLD, box, kViscosity, limited);
    op.set_positions(share(p.x, 3, s.offset, s.n), p.a[0]);
    // Each rank within the limit; together the slabs hold every mode (FFTW's local sizes cover all
    // planes) and the windows of every particle once.
    const double mine = static_cast<double>(op.memory_bytes());
    EXPECT_LE(mine, 600000.0);
    double total = 0.0;
    MPI_Allreduce(&mine, &total, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
    EXPECT_GE(total, kSlabBytesPerMode * kGridModes + 352.0 * 60.0);
    if (world_rank() == 0)
      std::printf("  [pse] split %d: relative difference %.2e, rank 0 memory %.0f bytes\n", static_cast<int>(split), d,
                  mine);
  }
}

TEST(MpiDistributedPse, LimitBelowOneRanksShareFailsEveryRank) {
  // Support 16 (448 bytes per particle), 2000 particles, limit 900000 bytes. PseRpy's estimate of
  // the whole grid, 755904 + 448 x 2000 = 1651904 bytes, fits the choice's budget on P >= 2 ranks
  // (P x 900000 >= 1.8e6) but not on one. All particles on the last rank: their windows alone,
  // 896000 bytes, plus its slab (at least 6 planes, 104832 bytes) exceed the limit, so every rank
  // fails with one message naming the last rank. The even split then fits: at most 12 planes and
  // 1000 particles a rank, 209664 + 448000 = 657664 bytes.
  const Geometry box = Geometry::periodic(12.0);
  const Particles p = uniform_set(2000, box.box(), 0.5, 22);
  const PseOptions limited = memory_test_options(16, 900000);
  const PseOptions unlimited = memory_test_options(16, kUnlimited);
  const int last = world_size() - 1;
  DistributedPseRpy op(MPI_COMM_WORLD, box, kViscosity, limited);
  const Shares all_last = shares_of(p.size(), Split::last_only);
  const std::string needle = world_size() == 1
                                 ? "max_memory_bytes"
                                 : "rank " + std::to_string(last) + " of " + std::to_string(world_size()) + " needs";
  const std::string message = expect_collective_error(
      [&] { op.set_positions(share(p.x, 3, all_last.offset, all_last.n), p.a[0]); }, ErrorCode::out_of_memory, needle);
  if (world_size() > 1) {
    EXPECT_NE(message.find("the windows of its 2000 particles: 896000 bytes"), std::string::npos) << message;
    EXPECT_NE(message.find("over the limit of 900000 bytes per rank"), std::string::npos) << message;
  }
  expect_collective_error([&] { (void)op.parameters(); }, ErrorCode::invalid_input, "positions not set");

  // A later set_positions of the even split (or, on one rank, an operator with an adequate limit)
  // works and equals the unlimited PseRpy to round-off (kRoundOff).
  const Shares even = shares_of(p.size(), Split::even);
  DistributedPseRpy adequate(MPI_COMM_WORLD, box, kViscosity, unlimited);
  DistributedPseRpy& used = world_size() == 1 ? adequate : op;
  used.set_positions(share(p.x, 3, even.offset, even.n), p.a[0]);
  if (world_size() > 1) {
    EXPECT_LE(op.memory_bytes(), 900000U);
  }
  std::vector<double> u(3 * even.n);
  used.apply(share(p.f, 3, even.offset, even.n), u);
  const double d = global_relative_difference(u, share(serial_velocities(p, box, unlimited), 3, even.offset, even.n));
  EXPECT_LE(d, kRoundOff);
  if (world_rank() == 0) std::printf("  [pse] even split after the refusal: relative difference %.2e\n", d);

  // 1000 bytes a rank: even the budget of all ranks together (at most 4000 bytes) is below the whole
  // grid's 1651904, so the parameter choice refuses it, naming that budget on several ranks.
  DistributedPseRpy tiny(MPI_COMM_WORLD, box, kViscosity, memory_test_options(16, 1000));
  expect_collective_error([&] { tiny.set_positions(share(p.x, 3, even.offset, even.n), p.a[0]); },
                          ErrorCode::out_of_memory, world_size() == 1 ? "max_memory_bytes" : " x max_memory_bytes");
}

TEST(MpiDistributedPse, BadInputOnOneRankFailsEveryRank) {
  const Geometry box = Geometry::periodic(12.0);
  const Particles p = uniform_set(60, box.box(), 1.0, 17);
  const Shares s = shares_of(p.size(), Split::even);
  const int last = world_size() - 1;
  DistributedPseRpy op(MPI_COMM_WORLD, box, kViscosity, double_grids(1e-4));
  std::vector<double> x = share(p.x, 3, s.offset, s.n), f = share(p.f, 3, s.offset, s.n), u(3 * s.n);
  expect_collective_error([&] { op.apply(f, u); }, ErrorCode::invalid_input, "positions not set");
  expect_collective_error([&] { op.sample(1, 0, u); }, ErrorCode::invalid_input, "positions not set");

  std::vector<double> bad_x = x;
  if (world_rank() == last && !bad_x.empty()) bad_x[1] = std::numeric_limits<double>::quiet_NaN();
  expect_collective_error([&] { op.set_positions(bad_x, 1.0); }, ErrorCode::invalid_input,
                          "rank " + std::to_string(last) + " of " + std::to_string(world_size()));
  expect_collective_error([&] { op.set_positions(x, world_rank() == last ? 0.0 : 1.0); }, ErrorCode::invalid_argument,
                          "radius");
  std::vector<double> radii(s.n, 1.0);
  if (world_rank() == last) radii.back() = 1.5;  // the last rank holds particles (even split of 60)
  expect_collective_error([&] { op.set_positions(x, radii); }, ErrorCode::not_supported, "equal radii only");
  std::vector<double> short_x(x.begin(), x.end() - (world_rank() == 0 && !x.empty() ? 1 : 0));
  expect_collective_error([&] { op.set_positions(short_x, 1.0); }, ErrorCode::invalid_input, "multiple of 3");
  expect_collective_error([&] { op.set_positions(std::vector<double>{}, 1.0); }, ErrorCode::invalid_input,
                          "no particles");

  op.set_positions(x, 1.0);
  std::vector<double> short_f(f.begin(), f.end() - (world_rank() == 0 && !f.empty() ? 1 : 0));
  expect_collective_error([&] { op.apply(short_f, u); }, ErrorCode::invalid_input, "local forces");
  std::vector<double> nan_f = f;
  if (world_rank() == last && !nan_f.empty()) nan_f[0] = std::numeric_limits<double>::quiet_NaN();
  expect_collective_error([&] { op.apply(nan_f, u); }, ErrorCode::invalid_input, "NaN");
  std::vector<double> long_w(u.size() + (world_rank() == last ? 3 : 0));
  expect_collective_error([&] { op.sample(1, 0, long_w); }, ErrorCode::invalid_input, "local output");
  expect_collective_error([&] { op.apply_sqrt(nan_f, u); }, ErrorCode::invalid_input, "NaN");
  expect_collective_error([&] { op.apply_with_noise(f, world_rank() == last ? -1.0 : 1.0, 1, 0, u); },
                          ErrorCode::invalid_argument, "noise_scale");
  std::vector<std::uint64_t> indices(s.n);
  std::iota(indices.begin(), indices.end(), std::uint64_t{s.offset});
  if (world_rank() == last) indices.back() = p.size();
  expect_collective_error([&] { op.apply_with_noise(f, 1.0, 1, 0, indices, u); }, ErrorCode::invalid_input,
                          "is not below the number of particles");
  if (world_rank() == last) indices.pop_back();
  expect_collective_error([&] { op.apply_with_noise(f, 1.0, 1, 0, indices, u); }, ErrorCode::invalid_input,
                          "one per local particle");
  rpyfmm::rpy::SqrtOptions lanczos;
  lanczos.method = world_rank() == last ? rpyfmm::rpy::SqrtMethod::lanczos : rpyfmm::rpy::SqrtMethod::split;
  expect_collective_error([&] { op.apply_sqrt(f, u, lanczos); }, ErrorCode::not_supported, "not offered across ranks");
  // Usable afterwards, and equal to the serial operator.
  op.apply(f, u);
  EXPECT_LE(global_relative_difference(u, share(serial_velocities(p, box, double_grids(1e-4)), 3, s.offset, s.n)),
            kRoundOff);

  expect_collective_error([&] { DistributedPseRpy o(MPI_COMM_WORLD, Geometry::open(), kViscosity); },
                          ErrorCode::not_supported, "periodic");
  PseOptions other = double_grids(1e-4);
  if (world_rank() == last) other.tolerance = 1e-5;
  if (world_size() > 1) {
    expect_collective_error([&] { DistributedPseRpy o(MPI_COMM_WORLD, box, kViscosity, other); },
                            ErrorCode::invalid_argument, "different");
  }
}
