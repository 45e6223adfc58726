// rpyfmm::bd — the one check of a thermal energy kT and of the noise variance it gives with the
// time step (the Integrator, the device engine, rigid-body dynamics; the config parser names the
// key first). docs/safety-limits.md, "Real parameters".
#pragma once

#include <cmath>
#include <string>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::bd {

/// Throws rpyfmm::Error (invalid_argument, naming `where`) unless kT is finite and >= 0 and, unless
/// 0, a normal number; and, for kT > 0, unless `variance` (the noise variance the step forms from
/// kT and dt, named by `variance_name`, e.g. "2 kT dt") is finite and normal. A subnormal kT, or a
/// variance that underflows, made every Brownian displacement 0 (or a few ulps) although kT > 0
/// (kT = 5e-324 gave 2 kT dt = 0 at dt = 0.01): the run was deterministic while claiming noise.
/// kT = 0 is the way to ask for deterministic dynamics. A variance that overflows made every
/// displacement infinite.
inline void require_thermal_energy(double kT, double variance, const char* where, const char* variance_name) {
  require(std::isfinite(kT) && kT >= 0.0, ErrorCode::invalid_argument, where,
          "kT must be finite and >= 0, got " + format_number(kT));
  if (kT == 0.0) return;
  require(std::isnormal(kT), ErrorCode::invalid_argument, where,
          "kT must be 0 or a normal number (>= 2.2e-308), got the subnormal " + format_number(kT) +
              " (kT = 0 gives deterministic dynamics)");
  require(std::isnormal(variance), ErrorCode::invalid_argument, where,
          std::string("the noise variance ") + variance_name + " = " + format_number(variance) +
              " (kT = " + format_number(kT) + ") " + (std::isfinite(variance) ? "underflows" : "overflows") +
              " double precision: the Brownian displacements would be " +
              (std::isfinite(variance) ? "lost to rounding (kT = 0 gives deterministic dynamics)" : "infinite") +
              "; choose units in which kT and dt are nearer 1");
}

}  // namespace rpyfmm::bd
