// rpyfmm fuzzing — the particle file reader of BD configs (bd/src/particles.cpp,
// read_particle_file: rows "x y z [type]", an XYZ-like text format), with two particle types.
#include "fuzz_file.hpp"
#include "rpyfmm/bd/force_field.hpp"
#include "rpyfmm/bd/particles.hpp"
#include "rpyfmm/core/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const rpyfmm::bd::ForceField forces(
      {rpyfmm::bd::ParticleType{.name = "A", .radius = 1.0}, rpyfmm::bd::ParticleType{.name = "B", .radius = 0.5}});
  const auto& path = rpyfmm::fuzz::write_scratch("particles", data, size);
  try {
    const rpyfmm::bd::InitialState s = rpyfmm::bd::read_particle_file(path, forces);
    if (s.positions.size() != 3 * s.types.size()) std::abort();
    for (auto t : s.types)
      if (t >= forces.types().size()) std::abort();
  } catch (const rpyfmm::Error&) {
  }
  return 0;
}
