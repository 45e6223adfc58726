// rpyfmm::mpi::DistributedPseRpy::communication(): the bytes a rank receives in a product are every
// value its exchanges carry from other ranks (the slabs' loads in, their velocities back, the halo's
// loads), counted from the exchange counts of set_positions; the seconds of the products add up
// to applies_seconds, and set_positions starts the sums again (docs/mpi.md, "Distributed PSE").
#include <gtest/gtest.h>
#include <mpi.h>

#include <cstdint>
#include <vector>

#include "mpi_test_support.hpp"
#include "rpyfmm/mpi/pse_operator.hpp"

using rpyfmm::mpi::DistributedPseRpy;
using rpyfmm::rpy::Geometry;
using rpyfmm::rpy::pse::PseOptions;
using namespace rpyfmm_mpi_test;

namespace {

constexpr double kSide = 16.0;

// The bytes of `width` doubles for every particle this rank's exchanges carry from other ranks: the
// positions' slab lists both ways (wave_received in, wave_sent's velocities back) and the halo.
std::uint64_t exchanged_bytes(const DistributedPseRpy& op, std::size_t width) {
  const auto& c = op.exchange_counts();
  return width * sizeof(double) * (c.wave_received + c.wave_sent + c.halo_received);
}

struct Operator {
  DistributedPseRpy op;
  std::vector<double> f, t;
  explicit Operator(std::size_t n_total)
      : op(MPI_COMM_WORLD, Geometry::periodic(kSide), kViscosity, [] {
          PseOptions o;
          o.tolerance = 1e-4;
          o.wave_precision = rpyfmm::rpy::pse::WavePrecision::double_precision;
          return o;
        }()) {
    Particles p = uniform_particles(n_total, kSide, 1.0, 1.0, 7);
    const Partition part = partition_of(n_total, Split::even);
    op.set_positions(share(p.x, 3, part.offset, part.n), 1.0);
    f = share(p.f, 3, part.offset, part.n);
    t = f;
  }
};

TEST(MpiDistributedPseStats, ProductBytesAreEveryExchangedValue) {
  Operator s(300);
  DistributedPseRpy& op = s.op;
  EXPECT_EQ(op.communication().apply_seconds, 0.0);
  EXPECT_EQ(op.communication().applies_seconds, 0.0);
  EXPECT_EQ(op.communication().apply_bytes_received, 0U);
  EXPECT_GE(op.communication().set_positions_seconds, 0.0);

  std::vector<double> u(s.f.size()), w(s.f.size());
  op.apply(s.f, u);
  // Three values per particle each way: forces to the slabs and the halo, velocities back.
  EXPECT_EQ(op.communication().apply_bytes_received, exchanged_bytes(op, 3));
  const double first = op.communication().apply_seconds;
  EXPECT_GE(first, 0.0);
  EXPECT_EQ(op.communication().applies_seconds, first);

  op.apply(s.f, s.t, u, w);
  // With rotation six: forces and torques in, velocities and angular velocities back.
  EXPECT_EQ(op.communication().apply_bytes_received, exchanged_bytes(op, 6));
  EXPECT_EQ(op.communication().applies_seconds, first + op.communication().apply_seconds);

  // The fused product adds the Lanczos iteration's real-space products: one halo exchange more per
  // product, so more bytes than apply's wherever there is a halo.
  const double before = op.communication().applies_seconds;
  const rpyfmm::rpy::SqrtReport report = op.apply_with_noise(s.f, 1.0, 3, 4, u);
  EXPECT_GT(report.iterations, 0);
  const auto& c = op.exchange_counts();
  EXPECT_EQ(op.communication().apply_bytes_received,
            exchanged_bytes(op, 3) + 3 * sizeof(double) * c.halo_received * report.operator_applications -
                3 * sizeof(double) * c.halo_received);
  EXPECT_EQ(op.communication().applies_seconds, before + op.communication().apply_seconds);
  if (world_size() == 1) {
    EXPECT_EQ(op.communication().apply_bytes_received, 0U);
  } else {  // the checks above compared counts of real exchanges: windows cross slabs, halos exist
    EXPECT_GT(c.wave_received + c.wave_sent, 0U);
    EXPECT_GT(c.halo_received, 0U);
  }
}

TEST(MpiDistributedPseStats, SetPositionsStartsTheSumsAgain) {
  Operator s(200);
  std::vector<double> u(s.f.size());
  s.op.apply(s.f, u);
  s.op.apply(s.f, u);
  Particles p = uniform_particles(200, kSide, 1.0, 1.0, 8);
  const Partition part = partition_of(200, Split::even);
  s.op.set_positions(share(p.x, 3, part.offset, part.n), 1.0);
  EXPECT_EQ(s.op.communication().applies_seconds, 0.0);
  EXPECT_EQ(s.op.communication().apply_seconds, 0.0);
  EXPECT_EQ(s.op.communication().apply_bytes_received, 0U);
}

}  // namespace
