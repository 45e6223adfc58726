// rpyfmm — PseRpyCuda in a build without CUDA: reports no device and refuses construction.
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/pse/pse_rpy_cuda.hpp"

namespace rpyfmm::rpy::pse {

struct PseRpyCuda::Impl {
  PseParameters params;
};

bool PseRpyCuda::device_available() {
  return false;
}

bool PseRpyCuda::device_values_finite(const double*, std::size_t) {
  fail(ErrorCode::not_supported, "PseRpyCuda::device_values_finite", "no CUDA support in this build");
}

PseRpyCuda::PseRpyCuda(Geometry geometry, double viscosity, const PseOptions&, const PseCudaOptions&)
    : PseOperator(geometry, viscosity, "PseRpyCuda") {
  fail(ErrorCode::not_supported, "PseRpyCuda", "this build of rpyfmm has no CUDA support (RPYFMM_USE_CUDA=OFF)");
}

PseRpyCuda::~PseRpyCuda() = default;

const PseParameters& PseRpyCuda::parameters() const {
  return impl_->params;
}
bool PseRpyCuda::device_cell_list_active() const {
  return false;
}
int PseRpyCuda::window_bin_edge() const {
  return 0;
}

SqrtReport PseRpyCuda::sample(std::uint64_t, std::uint64_t, std::span<double>) const {
  fail(ErrorCode::not_supported, "PseRpyCuda::sample", "no CUDA support in this build");
}

SqrtReport PseRpyCuda::apply_with_noise(std::span<const double>, double, std::uint64_t, std::uint64_t,
                                        std::span<double>) const {
  fail(ErrorCode::not_supported, "PseRpyCuda::apply_with_noise", "no CUDA support in this build");
}

SqrtReport PseRpyCuda::apply_with_noise_device(const double*, double, std::uint64_t, std::uint64_t, double*) const {
  fail(ErrorCode::not_supported, "PseRpyCuda::apply_with_noise_device", "no CUDA support in this build");
}
void PseRpyCuda::set_positions_device(const double*) {
  fail(ErrorCode::not_supported, "PseRpyCuda::set_positions_device", "no CUDA support in this build");
}
void PseRpyCuda::read_positions(std::vector<double>&) const {
  fail(ErrorCode::not_supported, "PseRpyCuda::positions", "no CUDA support in this build");
}
void PseRpyCuda::apply_device(const double*, double*) const {
  fail(ErrorCode::not_supported, "PseRpyCuda::apply_device", "no CUDA support in this build");
}
SqrtReport PseRpyCuda::sample_device(std::uint64_t, std::uint64_t, double*) const {
  fail(ErrorCode::not_supported, "PseRpyCuda::sample_device", "no CUDA support in this build");
}
void PseRpyCuda::apply_device(const double*, const double*, double*, double*) const {
  fail(ErrorCode::not_supported, "PseRpyCuda::apply_device", "no CUDA support in this build");
}

StageTimes PseRpyCuda::stage_times() const {
  return {};
}
void PseRpyCuda::reset_stage_times() const {}

void PseRpyCuda::on_positions_set() {}
void PseRpyCuda::do_apply(const double*, double*, std::size_t) const {
  fail(ErrorCode::not_supported, "PseRpyCuda::apply", "no CUDA support in this build");
}
SqrtReport PseRpyCuda::do_apply_sqrt(std::span<const double>, std::span<double>, std::size_t,
                                     const SqrtOptions&) const {
  fail(ErrorCode::not_supported, "PseRpyCuda::apply_sqrt", "no CUDA support in this build");
}
void PseRpyCuda::do_apply_rotation(const double*, const double*, double*, double*) const {
  fail(ErrorCode::not_supported, "PseRpyCuda::apply", "no CUDA support in this build");
}
SqrtReport PseRpyCuda::do_apply_sqrt_rotation(std::span<const double>, std::span<const double>, std::span<double>,
                                              std::span<double>, const SqrtOptions&) const {
  fail(ErrorCode::not_supported, "PseRpyCuda::apply_sqrt_rotation", "no CUDA support in this build");
}

}  // namespace rpyfmm::rpy::pse
