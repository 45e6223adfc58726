#include "rpyfmm/rpy/mobility_factory.hpp"

#include "rpyfmm/core/ranges.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/fmm/direct_simd.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"
#include "rpyfmm/rpy/free_draining.hpp"
#include "rpyfmm/rpy/pse/open_pse_rpy.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/pse/pse_rpy_cuda.hpp"

namespace rpyfmm::rpy {

const char* to_string(MobilityMethod method) {
  switch (method) {
    case MobilityMethod::none:
      return "none";
    case MobilityMethod::direct:
      return "direct";
    case MobilityMethod::fmm:
      return "fmm";
    case MobilityMethod::pse:
      return "pse";
    case MobilityMethod::automatic:
      return "auto";
  }
  return "unknown";
}

MobilityMethod mobility_method_from_string(const std::string& name) {
  for (auto m : {MobilityMethod::none, MobilityMethod::direct, MobilityMethod::fmm, MobilityMethod::pse,
                 MobilityMethod::automatic}) {
    if (name == to_string(m)) return m;
  }
  fail(ErrorCode::invalid_argument, "mobility method",
       "unknown method '" + name + "' (expected none, direct, fmm, pse or auto)");
}

const char* to_string(ComputeDevice device) {
  return device == ComputeDevice::cuda ? "cuda" : "cpu";
}

ComputeDevice compute_device_from_string(const std::string& name, const char* where) {
  if (name == "cpu") return ComputeDevice::cpu;
  if (name == "cuda") return ComputeDevice::cuda;
  fail(ErrorCode::invalid_argument, where, "unknown device '" + name + "' (expected cpu or cuda)");
}

// One-product crossovers of FmmRpy against DirectRpy, measured on a random cloud at phi = 0.05
// (1 thread, median products) for 3 / 6 / 9 / 12 digits: with the AVX2 direct kernels (AMD Zen 1) FmmRpy overtakes
// DirectRpy at ~1400 / 3500 / 6500 / 11000 particles; with the AVX-512 ones at ~2000 / 5000 /
// 12000 / 16000-18000 (Intel) and ~1200 / 4000 / 8500 / 13500 (AMD Zen 4). The AVX-512 row takes
// values between the two machines: near the crossover both operators cost about the same, so
// either machine loses little.
std::size_t default_fmm_crossover(double tolerance) {
  require_in_range(tolerance, 1e-15, 0.5, "default_fmm_crossover", "tolerance");
  const int digits = fmm::fmm_table_digits_for(tolerance);
  static constexpr std::size_t avx2[] = {1500, 3500, 7000, 11000}, avx512[] = {1500, 4500, 10000, 16000};
  const std::size_t table = digits <= 3 ? 0 : digits <= 6 ? 1 : digits <= 9 ? 2 : 3;
  return simd_level() == SimdLevel::avx512 ? avx512[table] : avx2[table];
}

namespace {
[[noreturn]] void unavailable(MobilityMethod method, const std::string& why) {
  fail(ErrorCode::not_supported, "make_mobility", std::string("mobility method '") + to_string(method) + "' " + why);
}
}  // namespace

std::unique_ptr<MobilityOperator> make_mobility(const MobilitySpec& spec, std::size_t n_particles) {
  ranges::require_in(ranges::kMobilityTolerance, spec.tolerance, "make_mobility", "mobility tolerance");
  ranges::require_in(ranges::kViscosity, spec.viscosity, "make_mobility", "viscosity");
  MobilityMethod method = spec.method;
  if (method == MobilityMethod::automatic) {
    if (spec.geometry.is_periodic()) {
      method = MobilityMethod::pse;
    } else if (const std::size_t crossover =
                   spec.fmm_crossover > 0 ? spec.fmm_crossover : default_fmm_crossover(spec.tolerance);
               n_particles >= crossover) {
      method = MobilityMethod::fmm;
    } else {
      method = MobilityMethod::direct;
    }
  }
  if (spec.device == ComputeDevice::cuda && method != MobilityMethod::pse) {
    unavailable(method, "has no CUDA version (device 'cuda' is for the pse method, periodic boxes)");
  }
  switch (method) {
    case MobilityMethod::none:
      return std::make_unique<FreeDrainingMobility>(spec.geometry, spec.viscosity);
    case MobilityMethod::direct:
      if (spec.geometry.is_periodic()) unavailable(method, "needs open geometry (use pse for periodic boxes)");
      return std::make_unique<DirectRpy>(spec.geometry, spec.viscosity);
    case MobilityMethod::fmm:
      if (spec.geometry.is_periodic()) unavailable(method, "needs open geometry (use pse for periodic boxes)");
      {
        FmmRpyOptions options;
        options.tolerance = spec.tolerance;  // relative l2 error of M F (FmmRpy accepts kMobilityTolerance)
        return std::make_unique<FmmRpy>(spec.geometry, spec.viscosity, options);
      }
    case MobilityMethod::pse: {
      pse::PseOptions options;
      options.tolerance = spec.tolerance;  // PseRpy accepts [1e-8, 0.1)
      options.fft_measure = spec.fft_measure;
      options.wave_precision = spec.wave_precision;
      if (spec.geometry.is_open()) {
        if (spec.device == ComputeDevice::cuda) {
          unavailable(method, "on device 'cuda' needs a periodic geometry (open boundaries run on the CPU)");
        }
        return std::make_unique<pse::OpenPseRpy>(spec.viscosity, options);
      }
      if (spec.device == ComputeDevice::cuda) {
        if (!pse::PseRpyCuda::device_available()) {
          unavailable(method, "on device 'cuda': no usable CUDA device (or a build without CUDA)");
        }
        return std::make_unique<pse::PseRpyCuda>(spec.geometry, spec.viscosity, options);
      }
      return std::make_unique<pse::PseRpy>(spec.geometry, spec.viscosity, options);
    }
    case MobilityMethod::automatic:
      break;
  }
  unavailable(method, "is unknown");
}

}  // namespace rpyfmm::rpy
