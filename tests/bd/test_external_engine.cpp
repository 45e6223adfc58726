// An Integrator stepped by an engine the caller gives it (StepEngine::external,
// rpyfmm/bd/stepper.hpp): the steps, positions, report and totals come from the engine, and the
// constructors refuse a mismatched engine or option.
#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <vector>

#include "rpyfmm/bd/integrator.hpp"
#include "rpyfmm/bd/stepper.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/rpy/free_draining.hpp"

namespace {

using rpyfmm::bd::Integrator;
using rpyfmm::bd::IntegratorOptions;
using rpyfmm::bd::StepEngine;

// Moves every particle by (1, 0, 0) per step; energy = the step count, one rebuild per step.
class ShiftEngine final : public rpyfmm::bd::Stepper {
 public:
  ShiftEngine(std::vector<double> x, std::uint64_t step) : x_(std::move(x)), f_(x_.size(), 0.5), step_(step) {}
  void step() override {
    for (std::size_t k = 0; k < x_.size(); k += 3) x_[k] += 1.0;
    ++step_;
  }
  [[nodiscard]] const std::vector<double>& positions() const override { return x_; }
  [[nodiscard]] const std::vector<double>& forces() const override { return f_; }
  [[nodiscard]] std::uint64_t step_count() const override { return step_; }
  [[nodiscard]] double potential_energy() const override { return static_cast<double>(step_); }
  [[nodiscard]] std::size_t rebuilds() const override { return step_; }
  [[nodiscard]] rpyfmm::StageTimes stage_times() const override {
    return {{"neighbours", 1.0}, {"forces", 2.0}, {"update", 3.0}};
  }

 private:
  std::vector<double> x_, f_;
  std::uint64_t step_;
};

IntegratorOptions external_options() {
  IntegratorOptions o;
  o.dt = 0.01;
  o.engine = StepEngine::external;
  return o;
}

Integrator make(const std::vector<double>& x, std::unique_ptr<rpyfmm::bd::Stepper> engine,
                IntegratorOptions options = external_options(), std::uint64_t first_step = 4) {
  return Integrator(std::make_unique<rpyfmm::rpy::FreeDrainingMobility>(rpyfmm::rpy::Geometry::open(), 1.0),
                    rpyfmm::bd::ForceField(), options, x, std::vector<std::uint32_t>(x.size() / 3, 0), {}, first_step,
                    std::move(engine));
}

TEST(ExternalEngine, TheIntegratorReadsTheEnginesState) {
  const std::vector<double> x{0, 0, 0, 5, 0, 0};
  Integrator bd = make(x, std::make_unique<ShiftEngine>(x, 4));
  EXPECT_EQ(bd.options().engine, StepEngine::external);
  EXPECT_STREQ(rpyfmm::bd::to_string(bd.options().engine), "external");
  bd.run(3);
  EXPECT_EQ(bd.step_count(), 7u);
  EXPECT_EQ(bd.positions()[0], 3.0);
  EXPECT_EQ(bd.positions()[3], 8.0);
  EXPECT_EQ(bd.last_forces()[1], 0.5);
  EXPECT_EQ(bd.last_report().potential_energy, 7.0);
  EXPECT_EQ(bd.neighbour_rebuilds(), 7u);
  EXPECT_EQ(bd.totals().steps, 3u);
  EXPECT_EQ(bd.totals().seconds.at("update"), 3.0);
  EXPECT_THROW((void)bd.neighbour_list(), rpyfmm::Error);
}

TEST(ExternalEngine, MismatchesAreRefused) {
  const std::vector<double> x{0, 0, 0, 5, 0, 0};
  // Another step, or other particles, than the Integrator's.
  EXPECT_THROW(make(x, std::make_unique<ShiftEngine>(x, 3)), rpyfmm::Error);
  EXPECT_THROW(make(x, std::make_unique<ShiftEngine>(std::vector<double>{0, 0, 0}, 4)), rpyfmm::Error);
  EXPECT_THROW(make(x, nullptr), rpyfmm::Error);
  // The engine needs StepEngine::external, and StepEngine::external needs an engine.
  IntegratorOptions cpu = external_options();
  cpu.engine = StepEngine::cpu;
  EXPECT_THROW(make(x, std::make_unique<ShiftEngine>(x, 4), cpu), rpyfmm::Error);
  try {
    Integrator bd(std::make_unique<rpyfmm::rpy::FreeDrainingMobility>(rpyfmm::rpy::Geometry::open(), 1.0),
                  rpyfmm::bd::ForceField(), external_options(), x, std::vector<std::uint32_t>(2, 0));
    FAIL() << "external without an engine accepted";
  } catch (const rpyfmm::Error& e) {
    EXPECT_NE(std::string(e.what()).find("needs the constructor that takes the engine"), std::string::npos);
  }
}

}  // namespace
