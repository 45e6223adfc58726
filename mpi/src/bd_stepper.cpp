// rpyfmm — a BD run of a configuration across MPI ranks (rpyfmm/mpi/bd_stepper.hpp).
#include "rpyfmm/mpi/bd_stepper.hpp"

#include <algorithm>
#include <array>
#include <cstddef>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "bd_gather.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/mpi/brownian_dynamics.hpp"

namespace rpyfmm::mpi {
namespace {

constexpr const char* kWhere = "bd across ranks";

// The whole system's values of one kind gathered on rank 0 once per step they are read at.
struct GatheredPerStep {
  static constexpr std::uint64_t kNever = std::numeric_limits<std::uint64_t>::max();
  std::vector<double> values{};
  std::uint64_t step = kNever;

  // Collective: the values at the engine's current step (`local`: this rank's, per per particle).
  const std::vector<double>& at(const DistributedBd& bd, std::span<const double> local, std::size_t per) {
    if (step != bd.step_count()) {
      values = detail::gather_by_index(bd.communicator(), bd.ids(), local, bd.global_size(), per, 0, kWhere);
      step = bd.step_count();
    }
    return values;
  }
};

// DistributedBd behind the Integrator's engine interface; the whole system's positions and forces
// (with rotation also the orientations and the last step's rotation vectors, with split
// displacements their two parts) gathered on rank 0 (the rank that writes the files, across_ranks)
// once per step they are read at, so that no other rank holds O(N) of them.
class DistributedStepper final : public bd::Stepper {
 public:
  explicit DistributedStepper(DistributedBd bd) : bd_(std::move(bd)) {}

  void step() override { bd_.step(); }
  [[nodiscard]] const std::vector<double>& positions() const override { return positions_.at(bd_, bd_.positions(), 3); }
  [[nodiscard]] const std::vector<double>& forces() const override { return forces_.at(bd_, bd_.last_forces(), 3); }
  /// With rotation (empty without): gathered on rank 0 as the positions.
  [[nodiscard]] const std::vector<double>& orientations() const override {
    return bd_.options().integrator.rotation ? orientations_.at(bd_, bd_.orientations(), 4) : orientations_.values;
  }
  [[nodiscard]] const std::vector<double>& rotations() const override {
    return bd_.options().integrator.rotation ? rotations_.at(bd_, bd_.last_rotations(), 3) : rotations_.values;
  }
  /// With inertial particles (empty without): gathered on rank 0 as the positions.
  [[nodiscard]] const std::vector<double>& velocities() const override {
    return bd_.inertial() ? velocities_.at(bd_, bd_.velocities(), 3) : velocities_.values;
  }
  /// Collective: summed over the ranks (DistributedBd::kinetic_temperature).
  [[nodiscard]] double kinetic_temperature() const override { return bd_.kinetic_temperature(); }
  /// With split displacements (empty without): gathered on rank 0 as the positions.
  [[nodiscard]] const std::vector<double>& deterministic_displacements() const override {
    const bool split = bd_.options().integrator.keep_split_displacements;
    return split ? deterministic_.at(bd_, bd_.deterministic_displacement(), 3) : deterministic_.values;
  }
  [[nodiscard]] const std::vector<double>& brownian_displacements() const override {
    const bool split = bd_.options().integrator.keep_split_displacements;
    return split ? brownian_.at(bd_, bd_.brownian_displacement(), 3) : brownian_.values;
  }
  /// With the SAC scheme (empty without): gathered on rank 0 as the positions.
  [[nodiscard]] const std::vector<std::uint32_t>& complex_ids() const override {
    if (!bd_.options().integrator.sac.enabled) return complex_ids_;
    const std::vector<double> mine(bd_.complex_ids().begin(), bd_.complex_ids().end());
    const std::vector<double>& all = complexes_.at(bd_, mine, 1);
    complex_ids_.resize(all.size());
    std::transform(all.begin(), all.end(), complex_ids_.begin(),
                   [](double id) { return static_cast<std::uint32_t>(id); });
    return complex_ids_;
  }
  /// Collective: summed over the ranks (DistributedBd::complex_counts).
  [[nodiscard]] std::array<std::uint64_t, 2> complex_counts() const override { return bd_.complex_counts(); }
  [[nodiscard]] std::uint64_t step_count() const override { return bd_.step_count(); }
  [[nodiscard]] double potential_energy() const override { return bd_.potential_energy(); }
  [[nodiscard]] std::size_t rebuilds() const override { return bd_.stats().rebuilds; }
  /// This rank's seconds: the lists, halo and partition as "neighbours", the halo's positions with
  /// the step as "update".
  [[nodiscard]] StageTimes stage_times() const override {
    const StageTimes& t = bd_.stats().seconds;
    return {{"neighbours", t.at("rebuild")}, {"forces", t.at("forces")}, {"update", t.at("update") + t.at("halo")}};
  }

 private:
  DistributedBd bd_;
  mutable GatheredPerStep positions_, forces_, orientations_, rotations_, velocities_, deterministic_, brownian_,
      complexes_;
  mutable std::vector<std::uint32_t> complex_ids_;
};

// The mobility of a run across ranks: its method, automatic counting as fmm in free space and as
// pse in a periodic box (rpy::make_mobility's choice for the serial run).
rpy::MobilityMethod method_across_ranks(const bd::RunConfig& config) {
  const rpy::MobilityMethod m = config.mobility.method;
  if (m != rpy::MobilityMethod::automatic) return m;
  return config.geometry.is_open() ? rpy::MobilityMethod::fmm : rpy::MobilityMethod::pse;
}

// The pse method's options as rpy::make_mobility gives them to the serial run's PseRpy. Across
// ranks the wave-space grids are double precision (DistributedPseRpy): wave_precision "single" and
// the device "cuda" are refused, "auto" runs the double grids.
rpy::pse::PseOptions pse_across_ranks(const rpy::MobilitySpec& spec) {
  require(spec.wave_precision != rpy::pse::WavePrecision::single_precision, ErrorCode::not_supported, kWhere,
          "mobility.wave_precision = \"single\" is not run across ranks (PSE across ranks has double-precision "
          "grids: use \"auto\" or \"double\")");
  require(spec.device == rpy::ComputeDevice::cpu, ErrorCode::not_supported, kWhere,
          std::string("mobility.device = \"") + rpy::to_string(spec.device) + "\" is not run across ranks (cpu only)");
  rpy::pse::PseOptions options;
  options.tolerance = spec.tolerance;
  options.fft_measure = spec.fft_measure;
  options.wave_precision = spec.wave_precision;
  return options;
}

}  // namespace

DistributedBdOptions distributed_bd_options(const bd::RunConfig& config) {
  DistributedBdOptions options;
  options.integrator = config.integrator;
  options.neighbours = config.neighbours;
  options.viscosity = config.mobility.viscosity;
  options.method = method_across_ranks(config);
  options.fmm.tolerance = config.mobility.tolerance;
  if (options.method == rpy::MobilityMethod::pse) options.pse = pse_across_ranks(config.mobility);
  options.curve = config.partition.curve == bd::PartitionSpec::Curve::hilbert ? SfcCurve::hilbert : SfcCurve::morton;
  options.repartition_imbalance = config.partition.repartition_imbalance;
  options.repartition_cost = config.partition.repartition_cost == bd::PartitionSpec::Cost::measured_time
                                 ? DistributedBdOptions::Cost::measured_time
                                 : DistributedBdOptions::Cost::model;
  return options;
}

BdShare block_share(int rank, int ranks, std::span<const double> positions, std::span<const std::uint32_t> types,
                    bool rotation, std::span<const double> orientations, std::span<const double> velocities) {
  const auto p = static_cast<std::uint64_t>(ranks), r = static_cast<std::uint64_t>(rank);
  const std::uint64_t n = types.size(), first = r * n / p, last = (r + 1) * n / p;
  const auto rows = [&](std::span<const double> values, std::uint64_t per) {
    const std::span<const double> block = values.subspan(per * first, per * (last - first));
    return std::vector<double>(block.begin(), block.end());
  };
  BdShare share;
  share.positions = rows(positions, 3);
  share.types.assign(types.begin() + static_cast<std::ptrdiff_t>(first),
                     types.begin() + static_cast<std::ptrdiff_t>(last));
  for (std::uint64_t i = first; i < last; ++i) share.ids.push_back(i);
  if (rotation && !orientations.empty()) share.orientations = rows(orientations, 4);
  if (!velocities.empty()) share.velocities = rows(velocities, 3);
  return share;
}

std::unique_ptr<bd::Stepper> make_distributed_stepper(MPI_Comm comm, const bd::RunConfig& config,
                                                      const bd::ForceField& forces, std::span<const double> positions,
                                                      std::span<const std::uint32_t> types,
                                                      std::span<const double> orientations,
                                                      std::span<const double> velocities, std::uint64_t first_step) {
  const Communicator world(comm);
  BdShare share =
      block_share(world.rank(), world.size(), positions, types, config.integrator.rotation, orientations, velocities);
  return std::make_unique<DistributedStepper>(
      DistributedBd(comm, forces, config.geometry, distributed_bd_options(config), std::move(share), first_step));
}

bd::RunOptions across_ranks(MPI_Comm comm, bd::RunOptions options) {
  const Communicator world(comm);
  options.engine = [comm](const bd::RunConfig& config, const bd::ForceField& forces, std::span<const double> x,
                          std::span<const std::uint32_t> types, std::span<const double> orientations,
                          std::span<const double> velocities, std::uint64_t first_step) {
    return make_distributed_stepper(comm, config, forces, x, types, orientations, velocities, first_step);
  };
  options.engine_name = "mpi";
  options.writes_files = world.rank() == 0;
  if (world.rank() != 0) options.progress = nullptr;
  options.agree = [world](const std::optional<Error>& problem) { world.agree(problem); };
  return options;
}

}  // namespace rpyfmm::mpi
