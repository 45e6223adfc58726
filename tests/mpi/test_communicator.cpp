// rpyfmm::mpi::Communicator: rank and size, and collective error agreement (every rank throws the
// same rpyfmm::Error naming the first failing rank, whichever ranks failed).
#include <gtest/gtest.h>
#include <mpi.h>

#include <cstddef>
#include <new>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "alltoallv.hpp"
#include "expect_error.hpp"
#include "mpi_test_support.hpp"
#include "rpyfmm/mpi/communicator.hpp"

using rpyfmm::Error;
using rpyfmm::ErrorCode;
using rpyfmm::mpi::Communicator;
using rpyfmm_mpi_test::expect_collective_error;
using rpyfmm_mpi_test::world_rank;
using rpyfmm_mpi_test::world_size;

TEST(MpiCommunicator, RankAndSizeOfTheCommunicator) {
  const Communicator world(MPI_COMM_WORLD);
  EXPECT_EQ(world.rank(), world_rank());
  EXPECT_EQ(world.size(), world_size());
  EXPECT_EQ(world.get(), MPI_COMM_WORLD);
  const Communicator self(MPI_COMM_SELF);
  EXPECT_EQ(self.rank(), 0);
  EXPECT_EQ(self.size(), 1);
}

TEST(MpiCommunicator, NullCommunicatorIsRefused) {
  rpyfmm_test::expect_error([] { Communicator c(MPI_COMM_NULL); }, ErrorCode::invalid_argument, "MPI_COMM_NULL");
}

TEST(MpiCommunicator, AgreeWithoutProblemsReturnsOnEveryRank) {
  const Communicator world(MPI_COMM_WORLD);
  for (int i = 0; i < 3; ++i) EXPECT_NO_THROW(world.agree(std::nullopt));
  EXPECT_NO_THROW(world.run([] {}));
}

TEST(MpiCommunicator, ProblemOnTheLastRankOnlyFailsEveryRank) {
  const Communicator world(MPI_COMM_WORLD);
  const int last = world.size() - 1;
  const std::string expected =
      "rank " + std::to_string(last) + " of " + std::to_string(world.size()) + ": test: bad value 7";
  const std::string message = expect_collective_error(
      [&] {
        world.agree(world.rank() == last ? std::optional<Error>(Error(ErrorCode::invalid_input, "test: bad value 7"))
                                         : std::nullopt);
      },
      ErrorCode::invalid_input, "bad value 7");
  EXPECT_EQ(message, expected);
  // The ranks are still in step: a later agreement without problems returns everywhere.
  EXPECT_NO_THROW(world.agree(std::nullopt));
}

TEST(MpiCommunicator, LowestFailingRankIsReportedWithTheCountOfOthers) {
  const Communicator world(MPI_COMM_WORLD);
  const int p = world.size();
  // Every rank fails with its own message: rank 0's is reported.
  const std::string all = expect_collective_error(
      [&] {
        world.run(
            [&] { throw Error(ErrorCode::numerical_failure, "problem of rank " + std::to_string(world.rank())); });
      },
      ErrorCode::numerical_failure, "rank 0 of " + std::to_string(p) + ": problem of rank 0");
  if (p > 1) {
    EXPECT_NE(all.find("(all " + std::to_string(p) + " ranks failed)"), std::string::npos) << all;
  }
  if (p >= 3) {
    // Ranks 1 and 2 fail: rank 1 is reported, with one other.
    const std::string two = expect_collective_error(
        [&] {
          world.run([&] {
            if (world.rank() == 1 || world.rank() == 2) throw Error(ErrorCode::invalid_argument, "x");
          });
        },
        ErrorCode::invalid_argument, "rank 1 of " + std::to_string(p) + ": x (1 other rank failed too)");
    (void)two;
  }
}

TEST(MpiCommunicator, RunMapsOtherExceptionsToErrorCodes) {
  const Communicator world(MPI_COMM_WORLD);
  const int last = world.size() - 1;
  expect_collective_error(
      [&] {
        world.run([&] {
          if (world.rank() == last) throw std::bad_alloc();
        });
      },
      ErrorCode::out_of_memory, "out of memory");
  expect_collective_error(
      [&] {
        world.run([&] {
          if (world.rank() == 0) throw std::runtime_error("plain runtime error");
        });
      },
      ErrorCode::invalid_input, "rank 0 of " + std::to_string(world.size()) + ": plain runtime error");
}

// The nonblocking exchange delivers what the blocking one delivers: rank r sends rank s the values
// 1000 r + 10 s + k for k < (r + s) % 3 (some empty), progressed by tests before the wait.
TEST(MpiCommunicator, PendingAlltoallvDeliversTheBlockingExchangesValues) {
  const Communicator world(MPI_COMM_WORLD);
  const auto ranks = static_cast<std::size_t>(world.size()), me = static_cast<std::size_t>(world.rank());
  std::vector<std::vector<double>> send(ranks);
  std::vector<std::size_t> counts(ranks);
  for (std::size_t r = 0; r < ranks; ++r) {
    for (std::size_t k = 0; k < (me + r) % 3; ++k) send[r].push_back(1000.0 * me + 10.0 * r + k);
    counts[r] = (r + me) % 3;
  }
  const std::vector<double> blocking = rpyfmm::mpi::detail::alltoallv(world, send, counts, "test", "values");
  rpyfmm::mpi::detail::PendingAlltoallv pending(world, send, counts, "test", "values");
  for (int k = 0; k < 3; ++k) pending.test();
  const std::vector<double> got = pending.wait();
  EXPECT_EQ(got, blocking);
  std::vector<double> expected;
  for (std::size_t r = 0; r < ranks; ++r)
    for (std::size_t k = 0; k < (r + me) % 3; ++k) expected.push_back(1000.0 * r + 10.0 * me + k);
  EXPECT_EQ(got, expected);
  {  // posted and never waited for: the destructor completes it
    rpyfmm::mpi::detail::PendingAlltoallv dropped(world, send, counts, "test", "values");
  }
}
