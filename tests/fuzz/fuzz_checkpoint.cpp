// rpyfmm fuzzing — the BD checkpoint reader (bd/src/checkpoint.cpp). The checksum would stop
// almost every mutation at the first check, so the target stamps the FNV-1a checksum of the
// input's body onto its last 8 bytes before reading: the fuzzer explores the record parsing
// behind it (N, the arrays, the config length), which a corrupt but checksummed file reaches.
#include <cstring>
#include <vector>

#include "fuzz_file.hpp"
#include "rpyfmm/bd/checkpoint.hpp"
#include "rpyfmm/core/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::vector<std::uint8_t> bytes(data, data + size);
  if (bytes.size() >= 16) {
    std::uint64_t h = 1469598103934665603ull;
    for (std::size_t i = 0; i + 8 < bytes.size(); ++i) {
      h ^= bytes[i];
      h *= 1099511628211ull;
    }
    std::memcpy(bytes.data() + bytes.size() - 8, &h, 8);
  }
  const auto& path = rpyfmm::fuzz::write_scratch("checkpoint", bytes.data(), bytes.size());
  try {
    const rpyfmm::bd::Checkpoint c = rpyfmm::bd::read_checkpoint(path);
    if (c.positions.size() != 3 * c.types.size() || c.reference_positions.size() != c.positions.size()) std::abort();
  } catch (const rpyfmm::Error&) {
  }
  return 0;
}
