// rpyfmm CLI — rigid bodies of beads read from the command line, shared by `rigid` and
// `rigid-bd`: --positions (beads, body after body), --radius | --radii, --body-sizes and
// --reference, checked against each other.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "rpyfmm/rpy/geometry.hpp"

namespace CLI {
class App;
}

namespace rpyfmm::cli {

struct BeadBodyArgs {
  std::string positions, radii, body_sizes, reference;
  double radius = 0.0;
  bool radius_given = false;  ///< --radius was on the command line (set by add_bead_body_options)
};

/// Adds --positions, --radius / --radii (exclusive), --body-sizes and --reference to `cmd`;
/// `positions_help` and `reference_help` describe them for this command.
void add_bead_body_options(CLI::App& cmd, BeadBodyArgs& args, const std::string& positions_help,
                           const std::string& reference_help);

struct BeadBodies {
  std::vector<double> x, radii;      ///< 3N positions, N radii
  std::vector<std::size_t> offsets;  ///< m + 1 body offsets
  std::vector<double> reference;     ///< 3m reference points, or empty when --reference was not given
  [[nodiscard]] std::size_t beads() const { return radii.size(); }
  [[nodiscard]] std::size_t bodies() const { return offsets.size() - 1; }
};

/// Body offsets (m + 1 entries from 0) from the body sizes of --body-sizes: whole numbers >= 1, at most
/// 2^53 in all (the
/// library checks >= 3 beads); rpyfmm::Error naming --body-sizes otherwise.
std::vector<std::size_t> body_offsets_from_sizes(const std::vector<double>& sizes);
/// --body-sizes read and checked against the n beads of --positions: its body offsets.
std::vector<std::size_t> read_body_offsets(const std::string& path, std::size_t n);
/// Exactly one of --radius (in range) and --radii was given; rpyfmm::Error naming --radius otherwise.
void require_one_radius(const BeadBodyArgs& args);

/// Reads and checks the files (sizes adding up to N, one radius option, m reference points);
/// rpyfmm::Error naming the option.
BeadBodies read_bead_bodies(const BeadBodyArgs& args);

/// Each body's beads relative to its reference point (3N): minimum images in a periodic
/// geometry, so a body given wrapped into the box keeps its shape. Fills `reference` with the
/// centroids (of minimum images relative to each body's first bead) when it is empty.
std::vector<double> body_frame_shape(const rpy::Geometry& geometry, const BeadBodies& bodies,
                                     std::vector<double>& reference);

}  // namespace rpyfmm::cli
