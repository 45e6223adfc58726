// rpyfmm::rpy — choosing a mobility operator by name, as BD configs, the CLI and Python do.
//
//   "none"   free draining (FreeDrainingMobility), any geometry
//   "direct" O(N^2) RPY sums (DirectRpy), open geometry
//   "fmm"    FMM-accelerated RPY (FmmRpy), open geometry
//   "pse"    Positively Split Ewald: pse::PseRpy in a periodic geometry, pse::OpenPseRpy (free
//            space, a compactly supported wave-space kernel) in open geometry
//   "auto"   open: direct below `fmm_crossover` particles (default: default_fmm_crossover),
//            fmm from there on; periodic: pse
//
// Device "cuda" (pse only, periodic) builds pse::PseRpyCuda instead of PseRpy: the same operator on
// a GPU (a build with CUDA and a usable device; wave_precision as on the CPU).
//
// A method that does not fit the geometry throws rpyfmm::Error(not_supported) naming it.
#pragma once

#include <cstddef>
#include <memory>
#include <string>

#include "rpyfmm/rpy/geometry.hpp"
#include "rpyfmm/rpy/mobility.hpp"
#include "rpyfmm/rpy/pse/pse_parameters.hpp"

namespace rpyfmm::rpy {

enum class MobilityMethod { none, direct, fmm, pse, automatic };

/// Where the operator computes: the CPU, or a CUDA GPU (the pse method only).
enum class ComputeDevice { cpu, cuda };

const char* to_string(ComputeDevice device);
/// "cpu" | "cuda"; throws invalid_argument naming the value (and `where`) otherwise.
ComputeDevice compute_device_from_string(const std::string& name, const char* where = "compute device");

const char* to_string(MobilityMethod method);
/// "none" | "direct" | "fmm" | "pse" | "auto"; throws naming the value otherwise.
MobilityMethod mobility_method_from_string(const std::string& name);

struct MobilitySpec {
  MobilityMethod method = MobilityMethod::automatic;
  /// Relative accuracy of the product M F (used by fmm and pse; direct is exact). In (0, 1).
  double tolerance = 1e-3;
  /// Solvent viscosity eta (> 0).
  double viscosity = 1.0;
  Geometry geometry = Geometry::open();
  /// "auto" switches from direct to fmm at this many particles (open geometry);
  /// 0 = default_fmm_crossover(tolerance) on this machine.
  std::size_t fmm_crossover = 0;
  /// pse: FFTW_MEASURE plans (pse::PseOptions::fft_measure): faster transforms for long
  /// runs, results reproducible to round-off instead of bit for bit across processes.
  bool fft_measure = false;
  /// pse: precision of the wave-space grids (pse::PseOptions::wave_precision); automatic
  /// takes single precision for tolerances >= 1e-5.
  pse::WavePrecision wave_precision = pse::WavePrecision::automatic;
  /// cuda: the pse method on a GPU (pse::PseRpyCuda); other methods refuse it. Needs a
  /// build with CUDA and a usable device (else not_supported, naming why).
  ComputeDevice device = ComputeDevice::cpu;
};

/// Particle count from which FmmRpy at `tolerance` beats DirectRpy per product, 1 thread: where
/// "auto" switches by default. It grows with the digits asked for (the FMM gets dearer, direct
/// sums do not) and is larger where the direct sums run the AVX-512 kernels (the measured values
/// are in mobility_factory.cpp).
std::size_t default_fmm_crossover(double tolerance);

/// Builds the operator for `spec` and `n_particles` (used by "auto"). Throws
/// rpyfmm::Error: invalid_argument for bad tolerance/viscosity, not_supported for a
/// method unavailable here or in this geometry.
std::unique_ptr<MobilityOperator> make_mobility(const MobilitySpec& spec, std::size_t n_particles);

}  // namespace rpyfmm::rpy
