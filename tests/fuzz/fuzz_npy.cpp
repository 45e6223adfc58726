// rpyfmm fuzzing — the .npy reader: every input is read as .npy (its first byte is made the
// magic's 0x93, so the fuzzer spends its time in the header and data parsing).
#include <string>

#include "fuzz_array.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::string bytes(reinterpret_cast<const char*>(data), size);
  if (bytes.empty()) return 0;
  bytes[0] = static_cast<char>(0x93);
  rpyfmm::fuzz::read_array_checked(bytes);
  return 0;
}
