// RigidBodies with extreme but valid solver options. The reference is the same bodies' mobility
// with the default options; a different restart length changes GMRES's path, not its answer.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/rigid_bodies.hpp"

namespace {

using rpyfmm::rpy::DirectRpy;
using rpyfmm::rpy::RigidBodies;

// restart = 2^31 - 1 allocated a Krylov basis of that many vectors up front and ended in
// std::bad_alloc; a cycle never needs more columns than max_iterations.
TEST(HostileRigidOptions, RestartLongerThanTheIterationLimit) {
  std::vector<double> x = rpyfmm::rpy::icosphere_beads(1);
  const std::size_t beads = x.size() / 3;
  for (std::size_t i = 0; i < 3 * beads; i += 3) x.insert(x.end(), {x[i] + 3.0, x[i + 1], x[i + 2]});
  const std::vector<std::size_t> offsets{0, beads, 2 * beads};
  const double a = rpyfmm::rpy::icosphere_bead_radius(1);
  const std::vector<double> ft{1, 0, 0, 0, 0.5, 0, 0, -1, 0, 0.3, 0, 0};
  std::vector<double> reference(12), u(12);
  DirectRpy m1, m2;
  RigidBodies plain(m1, {.tolerance = 1e-10});
  plain.set_configuration(x, a, offsets);
  plain.apply(ft, reference);
  RigidBodies long_cycles(m2, {.tolerance = 1e-10, .restart = std::numeric_limits<int>::max()});
  long_cycles.set_configuration(x, a, offsets);
  long_cycles.apply(ft, u);
  double error = 0.0, norm = 0.0;
  for (std::size_t i = 0; i < 12; ++i) {
    error += (u[i] - reference[i]) * (u[i] - reference[i]);
    norm += reference[i] * reference[i];
  }
  EXPECT_LT(std::sqrt(error / norm), 1e-8);
}

}  // namespace
