// rpyfmm fuzzing — the BD run config parser (bd/src/config.cpp over toml++): arbitrary text must
// parse or be refused with rpyfmm::Error; a parsed config must give a force field or an Error.
// Particles are not generated (that is sized by the config, by design).
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "rpyfmm/bd/config.hpp"
#include "rpyfmm/core/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const rpyfmm::bd::RunConfig config =
        rpyfmm::bd::parse_config(std::string_view(reinterpret_cast<const char*>(data), size), "fuzz.toml");
    (void)rpyfmm::bd::make_force_field(config);
  } catch (const rpyfmm::Error&) {
  }
  return 0;
}
