// rpyfmm CLI — the bead / particle mobility operator chosen on the command line
// (--method, --tolerance, --viscosity, --box, --wave-precision, --device), shared by `mobility`
// and `rigid`. Every method goes through rpyfmm::rpy::make_mobility, the factory the BD
// engine uses too.
#pragma once

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "rpyfmm/rpy/mobility.hpp"

namespace CLI {
class App;
}

namespace rpyfmm::cli {

struct MobilityChoice {
  double viscosity = 1.0;
  std::string method = "direct";
  double tolerance = 1e-6;              // of fmm / pse (direct is exact)
  std::vector<double> box;              // periodic box: L or Lx Ly Lz (empty = free space)
  std::string wave_precision = "auto";  // pse: auto | single | double
  std::string device = "cpu";           // pse: cpu | cuda
};

/// Adds --viscosity, --method, --tolerance (former spelling --eps), --box, --wave-precision and --device to `cmd`.
void add_mobility_options(CLI::App& cmd, MobilityChoice& choice);
/// Whether the bodies of `command` (rigid, rigid-bd) run across `ranks` MPI ranks with this choice:
/// --method direct or fmm without --box, or --method pse with --box and wave
/// grids auto or double, on the CPU, whose viscosity and tolerance it checks as make_operator does.
/// Throws rpyfmm::Error (not_supported) naming `command` for another choice on more than one rank.
bool bodies_across_ranks(const MobilityChoice& choice, int ranks, const std::string& command);
/// The operator for n particles (validates the choice; rpyfmm::Error naming the option).
std::unique_ptr<rpy::MobilityOperator> make_operator(const MobilityChoice& choice, std::size_t n);
/// --box as a geometry: open space when empty, else the periodic box of L (a cube) or Lx Ly Lz
/// (rpyfmm::Error naming --box for another number of lengths or what Geometry::periodic refuses).
rpy::Geometry box_geometry(const std::vector<double>& box);

}  // namespace rpyfmm::cli
