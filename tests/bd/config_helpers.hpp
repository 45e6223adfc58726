// Test helpers for configs: the integrator of a parsed config, and a config text that must be
// refused with an error naming its key.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "rpyfmm/bd/config.hpp"
#include "rpyfmm/bd/integrator.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/rpy/mobility_factory.hpp"

namespace bdtest {

/// The integrator of a parsed config from the given positions and types.
inline rpyfmm::bd::Integrator make_integrator(const rpyfmm::bd::RunConfig& c, std::vector<double> x,
                                              std::vector<std::uint32_t> types) {
  const std::size_t n = types.size();
  return rpyfmm::bd::Integrator(rpyfmm::rpy::make_mobility(c.mobility, n), rpyfmm::bd::make_force_field(c),
                                c.integrator, std::move(x), std::move(types), c.neighbours);
}

/// parse_config(text) must throw an error that names 'key' and contains `why`.
inline void expect_refused(const std::string& text, const std::string& key, const std::string& why) {
  try {
    (void)rpyfmm::bd::parse_config(text, "bad");
    ADD_FAILURE() << "accepted: " << key << " (" << why << ")";
  } catch (const rpyfmm::Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("'" + key + "'"), std::string::npos) << key << ": " << what;
    EXPECT_NE(what.find(why), std::string::npos) << what;
  }
}

}  // namespace bdtest
