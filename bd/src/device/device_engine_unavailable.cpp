// rpyfmm::bd::device — DeviceEngine in a build without CUDA: no device, and construction refused
// with the reason (the other members are never reached: no object can be constructed).
#include "rpyfmm/bd/device/device_engine.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::bd::device {

struct DeviceEngine::Impl {};

bool DeviceEngine::device_available() {
  return false;
}

DeviceEngine::DeviceEngine(const ForceField&, std::vector<std::uint32_t>, rpy::Geometry, const EngineOptions&,
                           std::span<const double>, std::uint64_t) {
  fail(ErrorCode::not_supported, "bd device engine", "this build of rpyfmm has no CUDA support (RPYFMM_USE_CUDA=OFF)");
}

DeviceEngine::~DeviceEngine() = default;

void DeviceEngine::step() {}
void DeviceEngine::run(std::uint64_t) {}
std::vector<double> DeviceEngine::positions() const {
  return {};
}
std::vector<double> DeviceEngine::forces() const {
  return {};
}
const double* DeviceEngine::device_positions() const {
  return nullptr;
}
const double* DeviceEngine::device_forces() const {
  return nullptr;
}
int DeviceEngine::device() const {
  return -1;
}
double DeviceEngine::potential_energy() const {
  return 0.0;
}
NeighbourRows DeviceEngine::neighbour_rows() const {
  return {};
}
std::uint64_t DeviceEngine::step_count() const {
  return 0;
}
std::size_t DeviceEngine::rebuilds() const {
  return 0;
}
bool DeviceEngine::last_step_rebuilt() const {
  return false;
}
StageTimes DeviceEngine::stage_times() const {
  return {};
}
std::optional<DriftNoiseReport> DeviceEngine::mobility_report() const {
  return std::nullopt;
}

}  // namespace rpyfmm::bd::device
