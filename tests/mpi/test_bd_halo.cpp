// The halo selection of distributed Brownian dynamics and of the distributed PSE real-space sum
// (mpi/src/bd_halo.hpp): each rank publishes a cover of its particles by tight boxes, and sends
// every other rank its particles within the list radius of that cover. Checked against a brute-force
// search over all pairs (minimum image in a periodic box): nothing within the radius of another
// rank's particle is missed, and a rank whose particles fill a slab of the box receives a halo of
// the slab's surface, not of the whole system.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "bd_halo.hpp"
#include "mpi_test_support.hpp"
#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/rpy/geometry.hpp"

namespace {

using rpyfmm::mpi::Communicator;
using rpyfmm::mpi::detail::Box;
using rpyfmm::rpy::Geometry;

// The squared minimum-image distance between two points.
double image_distance2(const double* p, const double* q, const Geometry& g) {
  double d2 = 0.0;
  for (int c = 0; c < 3; ++c) {
    double d = std::abs(p[c] - q[c]);
    if (g.is_periodic()) d = std::min(d, g.box()[c] - std::fmod(d, g.box()[c]));
    d2 += d * d;
  }
  return d2;
}

// All ranks' positions, gathered (the same on every rank), with the rank of each particle.
struct Everyone {
  std::vector<double> x;
  std::vector<int> rank;
};

Everyone gather_all(const Communicator& comm, const std::vector<double>& mine) {
  const int count = static_cast<int>(mine.size());
  std::vector<int> counts(comm.size()), displs(comm.size(), 0);
  MPI_Allgather(&count, 1, MPI_INT, counts.data(), 1, MPI_INT, comm.get());
  for (int r = 1; r < comm.size(); ++r) displs[r] = displs[r - 1] + counts[r - 1];
  Everyone all;
  all.x.resize(static_cast<std::size_t>(displs.back() + counts.back()));
  MPI_Allgatherv(mine.data(), count, MPI_DOUBLE, all.x.data(), counts.data(), displs.data(), MPI_DOUBLE, comm.get());
  for (int r = 0; r < comm.size(); ++r) all.rank.insert(all.rank.end(), counts[r] / 3, r);
  return all;
}

// This rank's particles that lie within `radius` of some particle of rank r (brute force).
std::vector<std::uint32_t> needed_by(int r, const std::vector<double>& mine, const Everyone& all, const Geometry& g,
                                     double radius) {
  std::vector<std::uint32_t> needed;
  for (std::size_t i = 0; 3 * i < mine.size(); ++i) {
    for (std::size_t j = 0; j < all.rank.size(); ++j) {
      if (all.rank[j] == r && image_distance2(&mine[3 * i], &all.x[3 * j], g) <= radius * radius) {
        needed.push_back(static_cast<std::uint32_t>(i));
        break;
      }
    }
  }
  return needed;
}

// Rank r's particles: uniform in the slab r L / P <= x < (r + 1) L / P of the cube [0, L)^3,
// shifted by a whole box on some so that the wrap is exercised, and a few near the slab's faces.
std::vector<double> slab_share(int rank, int ranks, double L, std::size_t n, bool periodic) {
  std::mt19937_64 rng(1234 + static_cast<std::uint64_t>(rank));
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> x;
  for (std::size_t i = 0; i < n; ++i) {
    const double slab = (rank + (i % 17 == 0 ? 1e-9 : u(rng)) * (1.0 - 1e-9)) * L / ranks;
    const double shift = periodic && i % 5 == 0 ? L * (i % 2 == 0 ? 1.0 : -2.0) : 0.0;
    x.insert(x.end(), {slab + shift, L * u(rng), L * u(rng)});
  }
  return x;
}

void expect_halo_is_complete_and_small(const Geometry& g, double L, double radius) {
  const Communicator comm(MPI_COMM_WORLD);
  const std::size_t n = 600;
  const std::vector<double> mine = slab_share(comm.rank(), comm.size(), L, n, g.is_periodic());
  const auto cells = rpyfmm::mpi::detail::owned_cells(mine, g);
  const std::vector<std::vector<Box>> regions =
      rpyfmm::mpi::detail::gather_regions(comm, rpyfmm::mpi::detail::region_of(cells));
  ASSERT_EQ(regions.size(), static_cast<std::size_t>(comm.size()));
  for (const auto& region : regions) {
    EXPECT_GE(region.size(), 1u);
    EXPECT_LE(region.size(), 64u);
  }
  const auto send = rpyfmm::mpi::detail::select_halo(comm, cells, regions, g, radius);
  const Everyone all = gather_all(comm, mine);
  for (int r = 0; r < comm.size(); ++r) {
    if (r == comm.rank()) {
      EXPECT_TRUE(send[r].empty());
      continue;
    }
    EXPECT_TRUE(std::is_sorted(send[r].begin(), send[r].end()));
    EXPECT_EQ(std::adjacent_find(send[r].begin(), send[r].end()), send[r].end()) << "a particle sent twice";
    const std::vector<std::uint32_t> needed = needed_by(r, mine, all, g, radius);
    EXPECT_TRUE(std::includes(send[r].begin(), send[r].end(), needed.begin(), needed.end()))
        << "rank " << comm.rank() << " misses particles within " << radius << " of rank " << r;
    // The slabs are L / P wide and the radius a tenth of that at most: the particles within the
    // radius of a neighbouring slab fill a tenth of a slab, those of a far slab none (periodic:
    // two faces). The cover's boxes add a margin; half of the share bounds both with room.
    EXPECT_LE(send[r].size(), n / 2) << "rank " << comm.rank() << " sends rank " << r << " a halo of " << send[r].size()
                                     << " of its " << n << " particles";
  }
}

TEST(MpiBdHalo, CoverHaloHoldsEveryParticleWithinTheRadiusAndNotTheWholeShare) {
  const double L = 20.0;
  const int ranks = rpyfmm_mpi_test::world_size();
  expect_halo_is_complete_and_small(Geometry::periodic(L), L, 0.1 * L / ranks);
  expect_halo_is_complete_and_small(Geometry::open(), L, 0.1 * L / ranks);
}

TEST(MpiBdHalo, BoxDistanceIsTheMinimumOverPeriodicImages) {
  const Geometry g = Geometry::periodic(10.0, 8.0, 6.0);
  const Box a{{0.5, 1.0, 2.0}, {1.0, 2.0, 3.0}};
  const Box b{{9.0, 7.5, 2.5}, {9.5, 7.9, 2.8}};  // x gap 1.0 through the face, y gap 1.1, z overlaps
  EXPECT_NEAR(rpyfmm::mpi::detail::distance2(a, b, g), 1.0 + 1.21, 1e-12);
  EXPECT_NEAR(rpyfmm::mpi::detail::distance2(a, b, Geometry::open()), 8.0 * 8.0 + 5.5 * 5.5, 1e-12);
  EXPECT_EQ(rpyfmm::mpi::detail::distance2(a, a, g), 0.0);
}

}  // namespace
