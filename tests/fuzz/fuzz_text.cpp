// rpyfmm fuzzing — the text array reader: inputs that would be taken for .npy (first byte 0x93)
// are skipped, so every run exercises the line and number parsing.
#include <string_view>

#include "fuzz_array.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size > 0 && data[0] == 0x93) return 0;
  rpyfmm::fuzz::read_array_checked(std::string_view(reinterpret_cast<const char*>(data), size));
  return 0;
}
