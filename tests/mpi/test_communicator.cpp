// rpyfmm::mpi::Communicator: rank and size, and collective error agreement (every rank throws the
// same rpyfmm::Error naming the first failing rank, whichever ranks failed).
#include <gtest/gtest.h>
#include <mpi.h>

#include <new>
#include <optional>
#include <stdexcept>
#include <string>

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
