// GSD trajectories in a build without the gsd C library (cmake/RpyfmmGsd.cmake found no sources):
// the config parser refuses `[output] format = "gsd"` with gsd_unsupported_reason(), so nothing
// here is reached from a run; direct calls fail with the same reason.
#include "rpyfmm/bd/gsd_trajectory.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::bd {

bool gsd_supported() {
  return false;
}

std::string gsd_unsupported_reason() {
  return "this build has no GSD support (configured without the sources of the gsd C library, or with "
         "RPYFMM_WITH_GSD=OFF): run scripts/fetch-gsd.sh (scripts/install-deps.sh does) or pass "
         "-DRPYFMM_GSD_SOURCE_DIR=<an unpacked gsd source distribution>, then configure and build again";
}

struct GsdTrajectory::Handle {};

namespace {
[[noreturn]] void unsupported() {
  fail(ErrorCode::invalid_argument, "gsd", gsd_unsupported_reason());
}
}  // namespace

GsdTrajectory::GsdTrajectory() = default;
GsdTrajectory::~GsdTrajectory() = default;

bool GsdTrajectory::is_open() const {
  return false;
}

void GsdTrajectory::open_temporary() {
  unsupported();
}

void GsdTrajectory::create(const std::filesystem::path&) {
  unsupported();
}

void GsdTrajectory::reopen(const std::filesystem::path&, std::uint64_t, std::uint64_t) {
  unsupported();
}

void GsdTrajectory::publish() {}

void GsdTrajectory::write(std::span<const GsdChunk>) {
  unsupported();
}

void GsdTrajectory::flush() {}

}  // namespace rpyfmm::bd
