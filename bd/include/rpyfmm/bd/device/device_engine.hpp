// rpyfmm::bd::device — free-draining Brownian dynamics with every stage of a step on a CUDA
// device (docs/gpu-bd.md): the dynamic Verlet-list rebuild test, cell binning and Verlet rows
// (Tran et al. (2015), Sec. 3.1 and Algorithm 1), pair forces (LJ 36-18, WCA,
// soft, DLVO), bonds, external forces and the trap, the Philox noise keyed by (seed, step,
// particle) and the Euler-Maruyama update with the blow-up guard, with the physics of the CPU
// engine (Integrator with the free-draining mobility "none"). Positions stay on the device; they
// come to the host on request.
//
// With EngineOptions::pse the mobility stage is PSE's (periodic hydrodynamic interactions, Fiore,
// Balboa Usabiaga, Donev & Swan (2017), J. Chem. Phys. 146, 124116) through the device entry
// points of rpy::pse::PseRpyCuda, the positions and forces staying on the device.
//
// Not covered: rotation, inertial / SAC particles and force callbacks. Library users reach the
// engine through Integrator (IntegratorOptions::engine), which refuses those by name
// (docs/gpu-bd.md).
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "rpyfmm/bd/force_field.hpp"
#include "rpyfmm/bd/neighbour_list.hpp"
#include "rpyfmm/bd/sampling.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/rpy/geometry.hpp"
#include "rpyfmm/rpy/pse/pse_operator.hpp"

namespace rpyfmm::bd::device {

/// The step's parameters: those of IntegratorOptions that free draining reads, the viscosity of
/// the free-draining mobility, the neighbour-list options, and the global force of the force field
/// (ForceField::set_global_force; ForceField does not give it back).
struct EngineOptions {
  double dt = 0.0;                ///< > 0
  double kT = 1.0;                ///< >= 0 (0: no noise)
  std::uint64_t seed = 1;         ///< key of the noise, with the step and the particle
  double max_displacement = 1.0;  ///< blow-up guard, in radii (> 0)
  double viscosity = 1.0;         ///< eta of mu = 1 / (6 pi eta a) (> 0)
  std::array<double, 3> global_force{0.0, 0.0, 0.0};
  NeighbourOptions neighbours{};
  /// PSE hydrodynamic interactions (docs/gpu-bd.md, "PSE"): the operator of the step's product
  /// U = M F + sqrt(2 kT dt) / dt M^{1/2} z and dx = U dt, as the CPU engine's fused step. Not
  /// owned (it outlives the engine). Null: free draining with `viscosity`. HostEngine uses its
  /// host products (PseRpy); DeviceEngine needs rpy::pse::PseRpyCuda (its device entry points).
  rpy::pse::PseOperator* pse = nullptr;
  /// The sampler's options with pse: automatic or split (PSE's one-pass product).
  SqrtOptions sqrt{};
};

/// Verlet rows copied to the host: row i is indices[offsets[i], offsets[i + 1]), sorted.
struct NeighbourRows {
  std::vector<std::uint64_t> offsets;
  std::vector<std::uint32_t> indices;
  [[nodiscard]] std::span<const std::uint32_t> row(std::size_t i) const {
    return {indices.data() + offsets[i], static_cast<std::size_t>(offsets[i + 1] - offsets[i])};
  }
};

class DeviceEngine {
 public:
  /// True when a CUDA device is usable: the runtime answers, it counts at least one device, and
  /// this build carries a kernel image for it. False in a build without CUDA.
  static bool device_available();

  /// Particles of `types` at `positions` (3N, finite), the forces of `forces` (its callbacks are
  /// not run on the device), steps numbered from first_step. Throws rpyfmm::Error naming the bad
  /// option, or not_supported without a usable device.
  DeviceEngine(const ForceField& forces, std::vector<std::uint32_t> types, rpy::Geometry geometry,
               const EngineOptions& options, std::span<const double> positions, std::uint64_t first_step = 0);
  ~DeviceEngine();
  DeviceEngine(const DeviceEngine&) = delete;
  DeviceEngine& operator=(const DeviceEngine&) = delete;

  /// One step: rebuild test -> lists when needed -> forces -> noise and update. On an overlap,
  /// a broken bond or a blow-up, the positions stay at the last good step and rpyfmm::Error is
  /// thrown (invalid_input / numerical_failure), as Integrator::step does.
  void step();
  void run(std::uint64_t count);

  [[nodiscard]] std::vector<double> positions() const;  ///< 3N, unwrapped, copied from the device
  [[nodiscard]] std::vector<double> forces() const;     ///< at the start of the last step
  /// The positions and the forces at the start of the last step in device memory (3N each, in
  /// the particle order of the constructor: the cell sort works on a copy), on CUDA device
  /// device(), read in place (docs/python.md, "Device arrays"). The positions alternate between two
  /// arrays, one per step: the pointer holds the current step's positions until the next step; the
  /// forces stay at one address and each step rewrites them.
  [[nodiscard]] const double* device_positions() const;
  [[nodiscard]] const double* device_forces() const;
  [[nodiscard]] int device() const;  ///< the CUDA ordinal current at construction
  /// The potential energy at the start of the last step (each particle's share summed on the
  /// host in particle order, as ForceField::compute does).
  [[nodiscard]] double potential_energy() const;
  [[nodiscard]] NeighbourRows neighbour_rows() const;
  [[nodiscard]] std::uint64_t step_count() const;
  [[nodiscard]] std::size_t rebuilds() const;
  [[nodiscard]] bool last_step_rebuilt() const;
  /// Seconds spent per part over the steps taken, by CUDA events: "neighbours" (rebuilds),
  /// "forces", "update" (noise, update, guard and the next rebuild test), the parts of
  /// Table 2 of Tran et al. (2015) and the keys of IntegratorTotals::seconds.
  [[nodiscard]] StageTimes stage_times() const;
  /// The mobility product of the last step with EngineOptions::pse (as the CPU engine reports
  /// it); nullopt for free draining or before the first step.
  [[nodiscard]] std::optional<DriftNoiseReport> mobility_report() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rpyfmm::bd::device
