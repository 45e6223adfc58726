// Helpers of the tests of apply_block (several right-hand sides per product) on the distributed
// operators: blocks of force vectors of the whole set, each rank's share of a block, one
// right-hand side of a block, and the refusals of bad input that both operators share.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "mpi_test_support.hpp"

namespace rpyfmm_mpi_test {

/// nrhs force vectors of the whole set, one after another: the set's own forces first, then
/// uniform ones in [-s, s] with s = 10^(3 (k mod 3) - 3) for the k-th (magnitudes 1e-3, 1, 1e3:
/// every one within MobilityOperator's unscaled range, rpy/src/load_scaling.hpp).
inline std::vector<double> block_forces(const Particles& p, std::size_t nrhs, std::uint64_t seed) {
  std::vector<double> f(p.f);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (std::size_t k = 1; k < nrhs; ++k) {
    const double s = std::pow(10.0, 3.0 * static_cast<double>(k % 3) - 3.0);
    for (std::size_t i = 0; i < 3 * p.size(); ++i) f.push_back(s * u(rng));
  }
  return f;
}

/// Right-hand side k of a block of vectors of n3 entries each.
inline std::vector<double> column_of(const std::vector<double>& block, std::size_t n3, std::size_t k) {
  return {block.begin() + static_cast<std::ptrdiff_t>(k * n3),
          block.begin() + static_cast<std::ptrdiff_t>((k + 1) * n3)};
}

/// This rank's share (3 entries per particle) of each of the nrhs vectors of `block`, one after another.
inline std::vector<double> block_share(const std::vector<double>& block, std::size_t nrhs, const Partition& part) {
  const std::size_t n3 = block.size() / nrhs;
  std::vector<double> out;
  for (std::size_t k = 0; k < nrhs; ++k) {
    const std::vector<double> mine = share(column_of(block, n3, k), 3, part.offset, part.n);
    out.insert(out.end(), mine.begin(), mine.end());
  }
  return out;
}

/// Collective: the refusals of apply_block on bad input of one rank, on `op` with positions set on
/// an even split of n_total particles, this rank's block `f` of nrhs right-hand sides and velocities
/// `u` of its size; `where` names the call ("...::apply_block: "). Each bad input makes every rank
/// throw the same message, and good input then succeeds everywhere.
template <class Operator>
void expect_block_refusals(const Operator& op, const std::vector<double>& f, std::vector<double>& u, std::size_t nrhs,
                           std::size_t n_total, const std::string& where) {
  const int last = world_size() - 1;
  const auto rank_of = [](int r) { return "rank " + std::to_string(r) + " of " + std::to_string(world_size()) + ": "; };
  const std::size_t m3 = f.size() / nrhs;
  // nrhs = 0 on one rank, and different nrhs on the ranks.
  expect_collective_error([&] { op.apply_block(f, u, world_rank() == last ? 0 : nrhs); },
                          rpyfmm::ErrorCode::invalid_argument,
                          rank_of(last) + where + "number of right-hand sides must be > 0");
  if (world_size() > 1) {
    std::vector<double> longer(m3 * (nrhs + 1)), u_longer(longer.size());
    expect_collective_error(
        [&] {
          if (world_rank() == 0)
            op.apply_block(longer, u_longer, nrhs + 1);
          else
            op.apply_block(f, u, nrhs);
        },
        rpyfmm::ErrorCode::invalid_argument, "the ranks pass different numbers of right-hand sides (nrhs)");
  }
  // Sizes that are not 3 local_size() nrhs: forces one particle short on the last rank, velocities
  // of one right-hand side on rank 0.
  std::vector<double> short_f = f;
  if (world_rank() == last) short_f.resize(f.size() - 3);
  expect_collective_error([&] { op.apply_block(short_f, u, nrhs); }, rpyfmm::ErrorCode::invalid_input,
                          rank_of(last) + where + "local forces has");
  std::vector<double> u_one(world_rank() == 0 ? m3 : u.size());
  expect_collective_error([&] { op.apply_block(f, u_one, nrhs); }, rpyfmm::ErrorCode::invalid_input,
                          rank_of(0) + where + "local velocities has");
  // A NaN in the last right-hand side on the last rank, at its particle 2, component 1: named by
  // its flat index (2 m + 2, 1) with m local particles, as MobilityOperator::apply_block names it.
  std::vector<double> bad = f;
  if (world_rank() == last) bad[2 * m3 + 3 * 2 + 1] = std::numeric_limits<double>::quiet_NaN();
  const std::size_t last_n = split_counts(n_total, static_cast<std::size_t>(world_size()), Split::even).back();
  expect_collective_error(
      [&] { op.apply_block(bad, u, nrhs); }, rpyfmm::ErrorCode::invalid_input,
      rank_of(last) + where + "local forces entry (" + std::to_string(2 * last_n + 2) + ", 1) is NaN");
  EXPECT_NO_THROW(op.apply_block(f, u, nrhs));
}

}  // namespace rpyfmm_mpi_test
