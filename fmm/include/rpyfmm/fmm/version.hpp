#pragma once
namespace rpyfmm {
/// Library version string, e.g. "0.1.0".
const char* version() noexcept;
}  // namespace rpyfmm
