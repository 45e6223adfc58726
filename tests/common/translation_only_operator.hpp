// A mobility operator with translation only (supports_rotation() false, the interface's default),
// as a user's own operator may be: U = F. For the tests of how products, samplers and BD with
// rotation refuse an operator without the rotational blocks.
#pragma once

#include <algorithm>
#include <cstddef>
#include <string>

#include "rpyfmm/rpy/mobility.hpp"

namespace rpyfmm::testing {

class TranslationOnly final : public rpy::MobilityOperator {
 public:
  TranslationOnly() : MobilityOperator(rpy::Geometry::open(), 1.0, "TranslationOnly") {}
  [[nodiscard]] std::string name() const override { return "translation-only"; }

 protected:
  void on_positions_set() override {}
  void do_apply(const double* forces, double* velocities, std::size_t nrhs) const override {
    std::copy_n(forces, 3 * size() * nrhs, velocities);
  }
};

}  // namespace rpyfmm::testing
