// rpyfmm::bd — the checks of a [particles] spec that asks for generated particles (particles.hpp):
// counts within kParticleCount and the machine's memory, volume fractions that the placement can
// reach. parse_config names the same keys while parsing; make_particles repeats the checks for a
// RunConfig built in code, whose NaN volume fraction made random placement loop forever and whose
// count of 2^64 - 1 failed in std::length_error.
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>

#include "rpyfmm/bd/particles.hpp"
#include "rpyfmm/core/ranges.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::bd {

namespace {

[[noreturn]] void bad_key(const std::string& key, const std::string& what) {
  fail(ErrorCode::invalid_argument, "config", "key '" + key + "' " + what);
}

// A lower bound of the memory a BD run keeps per particle (positions, reference positions,
// forces, displacements, noise, neighbour lists, the mobility operator's copies): a count whose
// run could never fit is refused, naming the key, instead of failing with std::bad_alloc while
// the particles are placed.
constexpr std::uint64_t kBytesPerParticle = 256;

std::uint64_t physical_memory_bytes() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGE_SIZE);
  if (pages <= 0 || page <= 0) return std::numeric_limits<std::uint64_t>::max();
  return static_cast<std::uint64_t>(pages) * static_cast<std::uint64_t>(page);
}

// A volume fraction in (0, hi]: finite, not subnormal (the region's radius goes as phi^(-1/3)).
void require_fraction(double phi, double hi, const std::string& key) {
  if (!(std::isnormal(phi) && phi > 0.0 && phi <= hi))
    bad_key(key, "must lie in (0, " + format_number(hi) + "], got " + format_number(phi));
}

}  // namespace

void require_particle_count(std::uint64_t a, std::uint64_t b, const std::string& key) {
  const std::uint64_t max = ranges::kParticleCount.hi;
  if (a < 1 || b < 1) bad_key(key, "asks for no particles (the limit " + ranges::kParticleCount.str() + ")");
  if (a > max / b)
    bad_key(key, "asks for more than " + std::to_string(max) + " particles (the limit " + ranges::kParticleCount.str() +
                     ")");
  const std::uint64_t n = a * b, memory = physical_memory_bytes();
  if (n > memory / kBytesPerParticle)
    bad_key(key, "asks for " + std::to_string(n) + " particles, which need more than the " +
                     format_number(static_cast<double>(memory) / 1e9) + " GB of memory of this machine");
}

void check_particle_spec(const ParticleSpec& p, bool periodic) {
  using Source = ParticleSpec::Source;
  switch (p.source) {
    case Source::file:
      return;
    case Source::random:
    case Source::lattice:
      require_particle_count(p.count, 1, "particles.count");
      break;
    case Source::chains:
      require_particle_count(p.chains, p.beads, "particles.chains");
      if (!(std::isfinite(p.bond_length) && p.bond_length >= 0.0))
        bad_key("particles.bond_length", "must be finite and >= 0, got " + format_number(p.bond_length));
      break;
    case Source::clusters:
      require_particle_count(p.clusters, p.cluster_size, "particles.clusters");
      require_fraction(p.cluster_volume_fraction, kMaxClusterVolumeFraction, "particles.cluster_volume_fraction");
      break;
  }
  if (!periodic) require_fraction(p.volume_fraction, kMaxVolumeFraction, "particles.volume_fraction");
}

}  // namespace rpyfmm::bd
