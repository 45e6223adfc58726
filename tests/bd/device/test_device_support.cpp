// Which Integrator runs the device engine takes (rpyfmm/bd/device/device_support.hpp): free
// draining and periodic PSE with its split sampler are accepted and their options carried over;
// every other feature is refused with not_supported and a message naming it.
#include <gtest/gtest.h>

#include <string>

#include "rpyfmm/bd/device/device_support.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/free_draining.hpp"
#include "rpyfmm/rpy/pse/open_pse_rpy.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"

using rpyfmm::bd::IntegratorOptions;
using rpyfmm::bd::device::engine_options_for;
using rpyfmm::bd::device::require_device_support;

namespace {

/// The refusal's message, or "" when accepted.
std::string refusal(const IntegratorOptions& o, const rpyfmm::rpy::MobilityOperator& m) {
  try {
    require_device_support(o, m);
  } catch (const rpyfmm::Error& e) {
    EXPECT_EQ(e.code(), rpyfmm::ErrorCode::not_supported);
    return e.what();
  }
  return "";
}

}  // namespace

TEST(DeviceSupport, FreeDrainingAcceptedWithItsOptions) {
  IntegratorOptions o;
  o.dt = 3e-3;
  o.kT = 0.5;
  o.seed = 99;
  o.max_displacement = 0.4;
  const rpyfmm::rpy::FreeDrainingMobility m(rpyfmm::rpy::Geometry::open(), 2.5);
  EXPECT_EQ(refusal(o, m), "");
  const auto e = engine_options_for(o, m, {.skin = 0.2, .fixed_interval = 3}, {0.0, 0.0, -1.0});
  EXPECT_EQ(e.dt, 3e-3);
  EXPECT_EQ(e.kT, 0.5);
  EXPECT_EQ(e.seed, 99u);
  EXPECT_EQ(e.max_displacement, 0.4);
  EXPECT_EQ(e.viscosity, 2.5);
  EXPECT_EQ(e.neighbours.skin, 0.2);
  EXPECT_EQ(e.neighbours.fixed_interval, 3);
  EXPECT_EQ(e.global_force[2], -1.0);
}

TEST(DeviceSupport, OtherFeaturesRefusedByName) {
  const rpyfmm::rpy::FreeDrainingMobility none;
  IntegratorOptions o;
  o.dt = 1e-3;
  const rpyfmm::rpy::DirectRpy direct(rpyfmm::rpy::Geometry::open(), 1.0);
  EXPECT_NE(refusal(o, direct).find("free draining"), std::string::npos);
  IntegratorOptions rotation = o;
  rotation.rotation = true;
  EXPECT_NE(refusal(rotation, none).find("rotation"), std::string::npos);
  IntegratorOptions inertia = o;
  inertia.inertia = {std::nullopt, rpyfmm::bd::LangevinParticle{1.0, 2.0}};
  EXPECT_NE(refusal(inertia, none).find("Langevin"), std::string::npos);
  IntegratorOptions sac = o;
  sac.sac.enabled = true;
  EXPECT_NE(refusal(sac, none).find("SAC"), std::string::npos);
  IntegratorOptions split = o;
  split.keep_split_displacements = true;
  EXPECT_NE(refusal(split, none).find("split"), std::string::npos);
  EXPECT_THROW(engine_options_for(rotation, none, {}), rpyfmm::Error);
}

TEST(DeviceSupport, PeriodicPseAcceptedWithItsSampler) {
  IntegratorOptions o;
  o.dt = 1e-3;
  o.sqrt.method = rpyfmm::rpy::SqrtMethod::split;
  const rpyfmm::rpy::pse::PseRpy pse(rpyfmm::rpy::Geometry::periodic(10.0), 0.9);
  EXPECT_EQ(refusal(o, pse), "");
  const auto e = engine_options_for(o, pse, {});
  EXPECT_EQ(e.sqrt.method, rpyfmm::rpy::SqrtMethod::split);
  EXPECT_EQ(e.viscosity, 0.9);
  EXPECT_EQ(e.pse, nullptr) << "the caller hands the engine the operator it moves";
  IntegratorOptions chebyshev = o;
  chebyshev.sqrt.method = rpyfmm::rpy::SqrtMethod::chebyshev;
  EXPECT_NE(refusal(chebyshev, pse).find("chebyshev"), std::string::npos);
  const rpyfmm::rpy::pse::OpenPseRpy open(0.9);
  EXPECT_NE(refusal(o, open).find("'pse-open'"), std::string::npos);
}
