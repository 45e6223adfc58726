// rpyfmm::bd — initial configurations: random suspensions at volume fraction
// phi (random sequential addition without overlaps), simple cubic lattices,
// bead-spring chains (self-avoiding random walks), clusters, or a file.
#pragma once

#include <cstdint>
#include <filesystem>
#include <vector>

#include "rpyfmm/bd/config.hpp"
#include "rpyfmm/bd/force_field.hpp"

namespace rpyfmm::bd {

struct InitialState {
  std::vector<double> positions;     ///< 3N
  std::vector<std::uint32_t> types;  ///< N
  std::vector<Bond> bonds;           ///< chains: consecutive beads (bond type 0)
  std::vector<double> orientations;  ///< 4N quaternions w x y z from a file's columns; else empty
};

/// Generates or reads the particles of `config` (types resolved by name in `forces`).
/// Throws naming the [particles] key that makes it impossible (e.g. phi too high), or a file
/// with orientation columns when rotation is off.
InitialState make_particles(const RunConfig& config, const ForceField& forces);

/// Reads rows "x y z [type] [qw qx qy qz]" ('#' comments); type = index or type name; the
/// orientation (a quaternion, normalized later) on every row or on none.
InitialState read_particle_file(const std::filesystem::path& path, const ForceField& forces);

}  // namespace rpyfmm::bd
