// rpyfmm::bd — the run configuration (a TOML file; reference: docs/bd-config.md).
//
// Parsing is strict: a missing required key, an unknown key, a value of the
// wrong type or out of range throws rpyfmm::Error naming the key, e.g.
// "config: key 'integrator.dt' must be > 0, got -0.1".
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "rpyfmm/bd/force_field.hpp"
#include "rpyfmm/bd/integrator.hpp"
#include "rpyfmm/bd/neighbour_list.hpp"
#include "rpyfmm/rpy/geometry.hpp"
#include "rpyfmm/rpy/mobility_factory.hpp"

namespace rpyfmm::bd {

/// How the initial particles are made ([particles]).
struct ParticleSpec {
  enum class Source { file, random, lattice, chains, clusters };
  Source source = Source::random;
  std::filesystem::path file;                  ///< file: rows "x y z [type]" (type = index or name)
  std::size_t count = 0;                       ///< random, lattice: number of particles
  double volume_fraction = 0.05;               ///< random, lattice, chains, clusters: sets the region size
  std::vector<std::string> types{};            ///< generated particles' types (cycled); empty = first type
  std::size_t chains = 0, beads = 0;           ///< chains: number and length
  double bond_length = 0.0;                    ///< chains: initial bond length (0 = 2.1 a)
  std::size_t clusters = 0, cluster_size = 0;  ///< clusters: number and size
  double cluster_volume_fraction = 0.3;        ///< clusters: packing inside a cluster
  std::uint64_t seed = 1;                      ///< generator seed
};

/// The trajectory's file format ([output] format).
enum class TrajectoryFormat {
  xyz,  ///< extended XYZ text (output.hpp)
  gsd,  ///< HOOMD-blue's binary GSD (gsd_trajectory.hpp), in builds with GSD support
};

struct OutputSpec {
  std::filesystem::path dir = "bd-out";
  TrajectoryFormat format = TrajectoryFormat::xyz;
  std::string trajectory = "trajectory.xyz";  ///< default: "trajectory." + the format's name
  std::string log = "log.csv";
  std::string checkpoint = "checkpoint.bin";
  std::uint64_t trajectory_every = 100;   ///< 0 = no trajectory
  std::uint64_t log_every = 10;           ///< 0 = no log
  std::uint64_t checkpoint_every = 1000;  ///< 0 = only at the end (and on blow-up)
};

/// How a run across MPI ranks (rpyfmm::mpi::across_ranks; docs/mpi.md, "Brownian dynamics across
/// ranks") splits the particles ([partition]). A run in one process reads and ignores it, so one
/// config serves both.
struct PartitionSpec {
  enum class Curve { morton, hilbert };
  enum class Cost { model, measured_time };
  Curve curve = Curve::morton;  ///< the space-filling curve of the partitions
  /// A rebuild repartitions when the largest rank's cost exceeds this multiple of the mean (>= 1;
  /// infinity: never after the first partition).
  double repartition_imbalance = 1.25;
  Cost repartition_cost = Cost::model;  ///< model: particles + list entries; measured_time: seconds
};

struct NamedPair {
  std::string type1, type2;
  PairPotential potential;
};

struct RunConfig {
  rpy::Geometry geometry = rpy::Geometry::open();
  double viscosity = 1.0;
  std::vector<ParticleType> types{ParticleType{}};
  ParticleSpec particles;
  std::vector<NamedPair> pairs;
  std::optional<BondPotential> chain_bond;  ///< bonds between consecutive beads of generated chains
  std::array<double, 3> external_force{0, 0, 0};
  double trap_stiffness = 0.0;  ///< [external] harmonic trap at the origin (0 = none)
  /// Rotation (integrator.rotation, from [system] rotation): per-type torques and dipoles (one
  /// entry per entry of `types`), a torque on every particle, the uniform field on the dipoles.
  std::vector<TypeTorque> type_torques{TypeTorque{}};
  std::array<double, 3> external_torque{0, 0, 0};
  std::array<double, 3> dipole_field{0, 0, 0};
  IntegratorOptions integrator;
  std::uint64_t steps = 0;
  rpy::MobilitySpec mobility;
  NeighbourOptions neighbours;
  OutputSpec output;
  PartitionSpec partition;
  std::string text;    ///< the TOML source (stored in checkpoints)
  std::string source;  ///< file name or "<built-in demo>"
};

/// Parses TOML text; `source` names it in error messages.
RunConfig parse_config(std::string_view text, const std::string& source);
/// Reads and parses a file (io_error naming the file if it cannot be read).
RunConfig load_config(const std::filesystem::path& path);
/// The built-in demo: a sedimenting cloud of 2000 spheres with HI (`rpyfmm bd`).
std::string_view demo_config_text();

/// Builds the force field (types, pairs, external force, chain bonds; the torque field when
/// rotation is on) of a config.
ForceField make_force_field(const RunConfig& config);

}  // namespace rpyfmm::bd
