// rpyfmm::bd — an engine that takes an Integrator's steps in its place (docs/gpu-bd.md, docs/mpi.md):
// the device engine (CUDA, or its stages on the host), or an engine given by the caller
// (StepEngine::external, e.g. the engine across MPI ranks of rpyfmm/mpi/bd_stepper.hpp). The
// Integrator reads the state through this interface; the positions and forces are copied to the
// caller only when read (a trajectory frame, a log row, a checkpoint).
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <vector>

#include "rpyfmm/bd/sampling.hpp"
#include "rpyfmm/core/timer.hpp"

namespace rpyfmm::bd {

class Stepper {
 public:
  /// An engine's own arrays of the current step, read in place (docs/python.md, "Device
  /// arrays"): the positions (3N, unwrapped, particle order) and the forces at the start of the
  /// last step (3N), in device memory on CUDA device `device`, or in host memory (device < 0).
  /// Valid until the next step: a step may move the positions to another array and rewrites the
  /// forces.
  struct StateView {
    const double* positions = nullptr;
    const double* forces = nullptr;
    std::size_t size = 0;  ///< 3N
    int device = -1;       ///< CUDA ordinal; < 0: host memory
  };

  virtual ~Stepper() = default;
  /// One step: on an error the positions stay at the last good step.
  virtual void step() = 0;
  /// The positions at the current step (3N, unwrapped, the whole system), copied once per step
  /// asked (into the same array: a view of it shows the step it was last read at). An engine across
  /// processes may hold them on the process that writes the files alone (RunOptions::writes_files)
  /// and return an empty array elsewhere; every process then calls it at the same steps.
  [[nodiscard]] virtual const std::vector<double>& positions() const = 0;
  /// The forces at the start of the last step (3N; 0 before the first), copied and held as positions().
  [[nodiscard]] virtual const std::vector<double>& forces() const = 0;
  [[nodiscard]] virtual std::uint64_t step_count() const = 0;
  /// The potential energy at the start of the last step; 0 before the first (as
  /// Integrator::last_report() before a step).
  [[nodiscard]] virtual double potential_energy() const = 0;
  [[nodiscard]] virtual std::size_t rebuilds() const = 0;
  /// Seconds per part: "neighbours", "forces", "update" (with hydrodynamic interactions also
  /// "plan" and "drift").
  [[nodiscard]] virtual StageTimes stage_times() const = 0;
  /// The last step's mobility product (square-root iterations, products) where the engine runs
  /// hydrodynamic interactions; nullopt for free draining (one pass of mu F and sqrt(mu) z).
  [[nodiscard]] virtual std::optional<DriftNoiseReport> mobility_report() const { return std::nullopt; }
  /// With rotation (IntegratorOptions::rotation): the orientations at the current step (4N unit
  /// quaternions w x y z) and the rotation vectors of the last step (3N; 0 before the first), held
  /// and copied as positions(). An engine without rotation returns empty arrays.
  [[nodiscard]] virtual const std::vector<double>& orientations() const { return none_; }
  [[nodiscard]] virtual const std::vector<double>& rotations() const { return none_; }
  /// With inertial (Langevin) particles: the half-step velocities at the current step (3N, 0 for
  /// Brownian particles), held and copied as positions(), and their kinetic temperature
  /// (LangevinGroup::kinetic_temperature; an engine across processes may compute it collectively,
  /// every process then calls it at the same steps). An engine without them returns an empty array
  /// and 0.
  [[nodiscard]] virtual const std::vector<double>& velocities() const { return none_; }
  /// With split displacements (IntegratorOptions::keep_split_displacements): M F dt and
  /// sqrt(2 kT dt) M^{1/2} z of the last step (3N each), held and copied as positions(). An engine
  /// without them returns empty arrays.
  [[nodiscard]] virtual const std::vector<double>& deterministic_displacements() const { return none_; }
  [[nodiscard]] virtual const std::vector<double>& brownian_displacements() const { return none_; }
  [[nodiscard]] virtual double kinetic_temperature() const { return 0.0; }
  /// With the SAC scheme (IntegratorOptions::sac): each particle's complex at the current positions
  /// (N entries, Complexes::owner()'s values), held and copied as positions(), and the numbers of
  /// complexes and of adsorbed particles there (Complexes::count() and adsorbed_total(); an engine
  /// across processes may compute them collectively, every process then calls it at the same
  /// steps). An engine without the scheme returns an empty array and {0, 0}.
  [[nodiscard]] virtual const std::vector<std::uint32_t>& complex_ids() const { return no_ids_; }
  [[nodiscard]] virtual std::array<std::uint64_t, 2> complex_counts() const { return {0, 0}; }
  /// The engine's arrays read in place (the device engine's buffers, or its host launcher's
  /// arrays); nullopt for an engine that does not keep the whole system in one address space.
  [[nodiscard]] virtual std::optional<StateView> state_view() const { return std::nullopt; }

 private:
  const std::vector<double> none_{};
  const std::vector<std::uint32_t> no_ids_{};
};

}  // namespace rpyfmm::bd
