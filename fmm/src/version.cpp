#include "rpyfmm/fmm/version.hpp"
namespace rpyfmm {
const char* version() noexcept {
  return "0.1.0";
}
}  // namespace rpyfmm
