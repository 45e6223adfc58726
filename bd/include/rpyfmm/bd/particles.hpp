// rpyfmm::bd — initial configurations: random suspensions at volume fraction
// phi (random sequential addition without overlaps), simple cubic lattices,
// bead-spring chains (self-avoiding random walks), clusters, or a file.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
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

/// Largest volume fractions of generated particles: the region of all of them (open geometry)
/// and one cluster (random sequential addition stalls above them).
inline constexpr double kMaxVolumeFraction = 0.45;
inline constexpr double kMaxClusterVolumeFraction = 0.4;

/// Throws rpyfmm::Error (invalid_argument) naming `key` unless a x b particles (a count, or
/// chains x beads, clusters x cluster_size) are at least 1, within ranges::kParticleCount and within
/// the machine's physical memory at 256 bytes per particle; the product is formed without overflow.
void require_particle_count(std::uint64_t a, std::uint64_t b, const std::string& key);

/// Throws rpyfmm::Error (invalid_argument) naming the [particles] key unless a spec of generated
/// particles can be placed: counts as require_particle_count, volume fractions (open geometry;
/// clusters' in any geometry) normal and at most kMaxVolumeFraction / kMaxClusterVolumeFraction,
/// a finite bond length >= 0. Nothing to check for particles read from a file.
void check_particle_spec(const ParticleSpec& spec, bool periodic);

/// Generates or reads the particles of `config` (types resolved by name in `forces`).
/// Throws naming the [particles] key that makes it impossible (e.g. phi too high, or any spec
/// check_particle_spec refuses), or a file with orientation columns when rotation is off.
InitialState make_particles(const RunConfig& config, const ForceField& forces);

/// Reads rows "x y z [type] [qw qx qy qz]" ('#' comments); type = index or type name; the
/// orientation (a quaternion, normalized later) on every row or on none.
InitialState read_particle_file(const std::filesystem::path& path, const ForceField& forces);

}  // namespace rpyfmm::bd
