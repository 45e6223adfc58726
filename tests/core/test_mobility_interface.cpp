// The interface's own validation, exercised through a trivial operator
// (M = I / (6 pi eta a_i), i.e. free draining) so that it does not depend
// on any solver.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "rpyfmm/rpy/mobility.hpp"

namespace {
class FreeDraining final : public rpyfmm::rpy::MobilityOperator {
 public:
  explicit FreeDraining(rpyfmm::rpy::Geometry g = rpyfmm::rpy::Geometry::open(), double eta = 1.0)
      : MobilityOperator(g, eta, "FreeDraining") {}
  std::string name() const override { return "free-draining"; }
  int plans_built = 0;

 protected:
  void on_positions_set() override { ++plans_built; }
  void do_apply(const double* f, double* u, std::size_t nrhs) const override {
    const std::size_t n = size();
    for (std::size_t k = 0; k < nrhs; ++k)
      for (std::size_t i = 0; i < 3 * n; ++i)
        u[k * 3 * n + i] = f[k * 3 * n + i] / (6 * std::numbers::pi * viscosity() * radii()[i / 3]);
  }
};
}  // namespace

using rpyfmm::Error;

TEST(MobilityInterface, ValidatesPositionsOnce) {
  FreeDraining op;
  EXPECT_THROW(op.set_positions(std::vector<double>{}, 1.0), Error);
  EXPECT_THROW(op.set_positions(std::vector<double>{0, 0}, 1.0), Error);
  EXPECT_THROW(op.set_positions(std::vector<double>{0, 0, NAN}, 1.0), Error);
  EXPECT_THROW(op.set_positions(std::vector<double>{0, 0, 0}, -1.0), Error);
  EXPECT_THROW(op.set_positions(std::vector<double>{0, 0, 0, 1, 1, 1}, std::vector<double>{1.0}), Error);
  EXPECT_THROW(op.set_positions(std::vector<double>{0, 0, 0, 1, 1, 1}, std::vector<double>{1.0, 0.0}), Error);
  EXPECT_EQ(op.plans_built, 0);
  op.set_positions(std::vector<double>{0, 0, 0, 1, 1, 1}, std::vector<double>{1.0, 2.0});
  EXPECT_EQ(op.plans_built, 1);
  EXPECT_FALSE(op.equal_radii());
  EXPECT_EQ(op.size(), 2u);
}

TEST(MobilityInterface, ApplyChecksSizesAndFiniteness) {
  FreeDraining op;
  std::vector<double> f(6, 1.0), u(6);
  EXPECT_THROW(op.apply(f, u), Error);  // positions not set
  op.set_positions(std::vector<double>{0, 0, 0, 3, 0, 0}, 1.0);
  EXPECT_NO_THROW(op.apply(f, u));
  EXPECT_NEAR(u[0], 1.0 / (6 * std::numbers::pi), 1e-15);
  std::vector<double> short_f(5, 1.0);
  EXPECT_THROW(op.apply(short_f, u), Error);
  f[2] = INFINITY;
  EXPECT_THROW(op.apply(f, u), Error);
}

TEST(MobilityInterface, RejectsBadViscosityAndBox) {
  EXPECT_THROW(FreeDraining(rpyfmm::rpy::Geometry::open(), 0.0), Error);
  EXPECT_THROW(FreeDraining(rpyfmm::rpy::Geometry::open(), NAN), Error);
  EXPECT_THROW(rpyfmm::rpy::Geometry::periodic(-1.0), Error);
}

TEST(MobilityInterface, PeriodicWrapsPositions) {
  FreeDraining op(rpyfmm::rpy::Geometry::periodic(10.0));
  op.set_positions(std::vector<double>{-1, 11, 25, 0, 0, 0}, 1.0);
  EXPECT_NEAR(op.positions()[0], 9.0, 1e-12);
  EXPECT_NEAR(op.positions()[1], 1.0, 1e-12);
  EXPECT_NEAR(op.positions()[2], 5.0, 1e-12);
}

TEST(MobilityInterface, DenseAssemblyAndDivergence) {
  FreeDraining op;
  op.set_positions(std::vector<double>{0, 0, 0, 3, 0, 0}, 1.0);
  const auto m = op.assemble_dense();
  ASSERT_EQ(m.size(), 36u);
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j) EXPECT_DOUBLE_EQ(m[i * 6 + j], i == j ? 1.0 / (6 * std::numbers::pi) : 0.0);
  std::vector<double> div(6, 1.0);
  op.divergence(div);
  for (double d : div) EXPECT_EQ(d, 0.0);
}
