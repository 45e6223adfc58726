#include "bead_bodies.hpp"

#include <CLI/CLI.hpp>
#include <cmath>
#include <string>

#include "array_io.hpp"
#include "cli_common.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::cli {

void add_bead_body_options(CLI::App& cmd, BeadBodyArgs& args, const std::string& positions_help,
                           const std::string& reference_help) {
  cmd.add_option("--positions", args.positions, positions_help)->required();
  auto* radius = cmd.add_option("--radius", args.radius, "common bead radius a, in " + ranges::kRadius.str());
  auto* radii = cmd.add_option("--radii", args.radii, "per-bead radii (N,)");
  radius->excludes(radii);
  // Recorded when parsed, so that --radius 0 is refused rather than taken for "not given".
  radius->each([&args](const std::string&) { args.radius_given = true; });
  cmd.add_option("--body-sizes", args.body_sizes, "beads per body (m,), in the order of --positions")->required();
  cmd.add_option("--reference", args.reference, reference_help);
}

std::vector<std::size_t> body_offsets_from_sizes(const std::vector<double>& sizes) {
  // Sizes are read as doubles, which hold every whole number up to 2^53 exactly: a larger entry
  // (1e30 was called "not a whole number") or total is refused by name, and the offsets never wrap.
  constexpr std::size_t kMaxBeads = std::size_t{1} << 53;
  std::vector<std::size_t> offsets{0};
  for (std::size_t k = 0; k < sizes.size(); ++k) {
    const double s = sizes[k];
    const std::string entry = "entry " + std::to_string(k) + " (" + format_number(s) + ")";
    require(std::isfinite(s) && s >= 1.0 && s == std::floor(s), ErrorCode::invalid_input, "--body-sizes",
            entry + " is not a whole number of beads >= 1");
    require(s <= static_cast<double>(kMaxBeads), ErrorCode::invalid_input, "--body-sizes",
            entry +
                " is too large: a body holds at most 2^53 = 9007199254740992 beads (the largest whole number a "
                "double holds exactly)");
    const auto beads = static_cast<std::size_t>(s);
    require(beads <= kMaxBeads - offsets.back(), ErrorCode::invalid_input, "--body-sizes",
            "entries 0 to " + std::to_string(k) + " add up to more than 2^53 = 9007199254740992 beads");
    offsets.push_back(offsets.back() + beads);
  }
  return offsets;
}

std::vector<std::size_t> read_body_offsets(const std::string& path, std::size_t n) {
  std::vector<std::size_t> offsets = body_offsets_from_sizes(read_array(path).data);
  require(offsets.size() > 1, ErrorCode::invalid_input, "--body-sizes", "no bodies given");
  require(offsets.back() == n, ErrorCode::invalid_input, "--body-sizes",
          "the body sizes add up to " + std::to_string(offsets.back()) + " beads, but --positions has " +
              std::to_string(n));
  return offsets;
}

void require_one_radius(const BeadBodyArgs& args) {
  require(args.radius_given != !args.radii.empty(), ErrorCode::invalid_argument, "--radius",
          "give exactly one of --radius a or --radii R.npy");
  if (args.radius_given) ranges::require_in(ranges::kRadius, args.radius, "--radius", "radius");
}

BeadBodies read_bead_bodies(const BeadBodyArgs& args) {
  require_one_radius(args);
  BeadBodies b;
  b.x = as_points(read_array(args.positions), "positions");
  const std::size_t n = b.x.size() / 3;
  b.offsets = read_body_offsets(args.body_sizes, n);
  b.radii.assign(n, args.radius);
  if (!args.radius_given) b.radii = as_vector(read_array(args.radii), n, "radii");
  if (!args.reference.empty()) {
    b.reference = as_points(read_array(args.reference), "reference points");
    require(b.reference.size() == 3 * b.bodies(), ErrorCode::invalid_input, "--reference",
            "has " + std::to_string(b.reference.size() / 3) + " rows, expected " + std::to_string(b.bodies()) +
                " (one per body)");
  }
  return b;
}

std::vector<double> body_frame_shape(const rpy::Geometry& geometry, const BeadBodies& bodies,
                                     std::vector<double>& reference) {
  const auto minimum_image = [&geometry](double d[3]) {
    if (!geometry.is_periodic()) return;
    for (int c = 0; c < 3; ++c) d[c] -= geometry.box()[c] * std::nearbyint(d[c] / geometry.box()[c]);
  };
  const std::size_t m = bodies.bodies();
  const std::vector<double>& x = bodies.x;
  if (reference.empty()) {
    reference.assign(3 * m, 0.0);
    for (std::size_t k = 0; k < m; ++k) {
      const std::size_t first = bodies.offsets[k], count = bodies.offsets[k + 1] - first;
      double sum[3] = {0.0, 0.0, 0.0};
      for (std::size_t i = first; i < first + count; ++i) {
        double d[3];
        for (int c = 0; c < 3; ++c) d[c] = x[3 * i + c] - x[3 * first + c];
        minimum_image(d);
        for (int c = 0; c < 3; ++c) sum[c] += d[c];
      }
      for (int c = 0; c < 3; ++c) reference[3 * k + c] = x[3 * first + c] + sum[c] / double(count);
    }
  }
  std::vector<double> shape(x.size());
  for (std::size_t k = 0; k < m; ++k) {
    for (std::size_t i = bodies.offsets[k]; i < bodies.offsets[k + 1]; ++i) {
      double d[3];
      for (int c = 0; c < 3; ++c) d[c] = x[3 * i + c] - reference[3 * k + c];
      minimum_image(d);
      for (int c = 0; c < 3; ++c) shape[3 * i + c] = d[c];
    }
  }
  return shape;
}

}  // namespace rpyfmm::cli
