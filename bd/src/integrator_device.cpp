// rpyfmm::bd — the Integrator on the device engine (IntegratorOptions::engine; docs/gpu-bd.md):
// its start-up, its step with the report and totals of the CPU engine's free-draining or PSE
// step, and the accessors that read whichever engine holds the state.
#include <array>
#include <string>
#include <utility>

#include "device/device_stepper.hpp"
#include "rpyfmm/bd/device/device_support.hpp"
#include "rpyfmm/bd/integrator.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/pse/pse_operator.hpp"

namespace rpyfmm::bd {

void Integrator::start_device_engine(const NeighbourOptions& neighbours, bool orientations, bool velocities) {
  const char* where = "Integrator";
  device::EngineOptions engine = device::engine_options_for(options_, *mobility_, neighbours, forces_.global_force());
  // Accepted above: "none", or a periodic PSE operator, which the engine's steps move.
  if (mobility_->name() != "none") engine.pse = dynamic_cast<rpy::pse::PseOperator*>(mobility_.get());
  device::require_device_forces(forces_);
  require(!orientations, ErrorCode::invalid_argument, where, "orientations given but rotation is off");
  require(!velocities, ErrorCode::invalid_argument, where, "velocities given but no particle is inertial");
  const DeviceLauncher launcher = options_.engine == StepEngine::cuda ? DeviceLauncher::cuda : DeviceLauncher::host;
  device_ = device::make_stepper(launcher, forces_, types_, mobility_->geometry(), engine, x_, step_);
  std::vector<double>().swap(x_);  // the engine holds the positions
}

const StepReport& Integrator::device_step() {
  const std::size_t rebuilds = device_->rebuilds();
  device_->step();  // on an error the engine stays at the last good step
  StepReport rep;
  rep.neighbour_rebuild = device_->rebuilds() != rebuilds;
  rep.potential_energy = device_->potential_energy();
  rep.mobility_products = 1;  // mu F and sqrt(mu) z in one pass, as the CPU engine counts "none"
  if (const auto products = device_->mobility_report()) {  // PSE: as drift_and_noise_products reports it
    rep.sqrt_iterations = products->sqrt.iterations;
    rep.preconditioner_blocks = products->sqrt.preconditioner_blocks;
    rep.mobility_products = products->mobility_products;
    rep.shared_first_product = products->shared_first_product;
  }
  step_ = device_->step_count();
  ++totals_.steps;
  totals_.sqrt_iterations += static_cast<std::uint64_t>(rep.sqrt_iterations);
  totals_.mobility_products += static_cast<std::uint64_t>(rep.mobility_products);
  for (const auto& [part, seconds] : device_->stage_times()) totals_.seconds[part] = seconds;
  report_ = rep;
  return report_;
}

std::span<const double> Integrator::positions() const {
  return device_ ? std::span<const double>(device_->positions()) : std::span<const double>(x_);
}

std::span<const double> Integrator::last_forces() const {
  return device_ ? std::span<const double>(device_->forces()) : std::span<const double>(f_);
}

std::span<const double> Integrator::orientations() const {
  return device_ ? std::span<const double>(device_->orientations()) : std::span<const double>(q_);
}

std::span<const double> Integrator::last_rotations() const {
  return device_ ? std::span<const double>(device_->rotations()) : std::span<const double>(phi_);
}

std::span<const double> Integrator::deterministic_displacement() const {
  return device_ ? std::span<const double>(device_->deterministic_displacements()) : std::span<const double>(dx_det_);
}

std::span<const double> Integrator::brownian_displacement() const {
  return device_ ? std::span<const double>(device_->brownian_displacements()) : std::span<const double>(dx_brown_);
}

std::span<const double> Integrator::velocities() const {
  return device_ ? std::span<const double>(device_->velocities()) : inertial_.velocities();
}

double Integrator::kinetic_temperature() const {
  return device_ ? device_->kinetic_temperature() : inertial_.kinetic_temperature();
}

std::span<const std::uint32_t> Integrator::complex_ids() const {
  return device_ ? std::span<const std::uint32_t>(device_->complex_ids()) : complexes_.owner();
}

std::array<std::uint64_t, 2> Integrator::complex_counts() const {
  return device_ ? device_->complex_counts()
                 : std::array<std::uint64_t, 2>{complexes_.count(), complexes_.adsorbed_total()};
}

std::size_t Integrator::neighbour_rebuilds() const {
  return device_ ? device_->rebuilds() : list_.rebuilds();
}

std::optional<Stepper::StateView> Integrator::engine_state() const {
  return device_ ? device_->state_view() : std::nullopt;
}

const NeighbourList& Integrator::neighbour_list() const {
  require(!device_, ErrorCode::not_supported, "Integrator",
          std::string("neighbour_list(): the device engine (") + to_string(options_.engine) +
              ") keeps its Verlet rows on the device (neighbour_rebuilds() counts its builds)");
  return list_;
}

}  // namespace rpyfmm::bd
