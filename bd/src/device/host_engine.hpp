// rpyfmm::bd::device — the host launcher: the device engine's step (device_engine.hpp) with
// every stage run by a loop over the particles (slots, cells) that calls the stage's
// host-device function, as a CUDA kernel runs one thread per particle. It is the reference the
// device engine is checked against, and what the tests compare with the CPU engine where no
// device is present (tests/bd/device; docs/gpu-bd.md).
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "cell_grid.hpp"
#include "engine_tables.hpp"
#include "rebuild_schedule.hpp"
#include "rpyfmm/bd/device/device_engine.hpp"

namespace rpyfmm::bd::device {

class HostEngine {
 public:
  /// As DeviceEngine's constructor (same checks), on the host.
  HostEngine(const ForceField& forces, std::vector<std::uint32_t> types, rpy::Geometry geometry,
             const EngineOptions& options, std::span<const double> positions, std::uint64_t first_step = 0);

  /// One step: rebuild test -> lists when needed -> forces -> (PSE: the product) -> noise and update
  /// (DeviceEngine::step).
  void step();
  void run(std::uint64_t count);
  /// Builds the Verlet rows at the current positions (the schedule's builds; tests call it to
  /// compare the rows of given positions).
  void build_lists();

  [[nodiscard]] std::span<const double> positions() const { return x_; }
  [[nodiscard]] std::span<const double> forces() const { return f_; }
  [[nodiscard]] double potential_energy() const;
  [[nodiscard]] const NeighbourRows& neighbour_rows() const { return rows_; }
  [[nodiscard]] std::uint64_t step_count() const { return step_; }
  [[nodiscard]] std::size_t rebuilds() const { return schedule_.rebuilds(); }
  [[nodiscard]] bool last_step_rebuilt() const { return rebuilt_; }
  /// Seconds per part over the steps taken (DeviceEngine::stage_times; wall clock).
  [[nodiscard]] const StageTimes& stage_times() const { return times_; }
  /// The last step's PSE product (EngineOptions::pse); nullopt for free draining.
  [[nodiscard]] std::optional<DriftNoiseReport> mobility_report() const { return products_; }

 private:
  [[nodiscard]] CellGrid grid() const;
  void rows_from_all_pairs();
  void rows_from_cells(const CellGrid& g);
  void hydrodynamic_velocities();

  EngineTables t_;
  std::vector<double> x_, x_next_, reference_, f_, energy_;
  NeighbourRows rows_;
  std::uint64_t step_;
  RebuildSchedule schedule_;
  bool rebuilt_ = false;
  StageTimes times_{{"neighbours", 0.0}, {"forces", 0.0}, {"update", 0.0}};
  // PSE (EngineOptions::pse): the operator, its sampler options, the radii, the velocities and
  // the last product's report.
  rpy::pse::PseOperator* pse_ = nullptr;
  SqrtOptions sqrt_{};
  std::vector<double> radii_, u_;
  std::optional<DriftNoiseReport> products_;
};

}  // namespace rpyfmm::bd::device
