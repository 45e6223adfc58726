#include "rpyfmm/bd/torque_field.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "rpyfmm/bd/quaternion.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::bd {

namespace {
constexpr const char* kWhere = "TorqueField";

bool any_nonzero(const std::array<double, 3>& v) {
  return v[0] != 0.0 || v[1] != 0.0 || v[2] != 0.0;
}

void require_finite3(const std::array<double, 3>& v, const std::string& what) {
  require(std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]), ErrorCode::invalid_argument, kWhere,
          what + " must be finite");
}
}  // namespace

TorqueField::TorqueField(std::vector<TypeTorque> types, const std::array<double, 3>& torque,
                         const std::array<double, 3>& field)
    : types_(std::move(types)), torque_(torque), field_(field) {
  require_finite3(torque_, "the torque on every particle");
  require_finite3(field_, "the dipole field");
  bool dipoles = false, type_torques = false;
  for (std::size_t t = 0; t < types_.size(); ++t) {
    const std::string name = "type " + std::to_string(t);
    require_finite3(types_[t].torque, "the torque of " + name);
    require(std::isfinite(types_[t].dipole) && types_[t].dipole >= 0.0, ErrorCode::invalid_argument, kWhere,
            "the dipole of " + name + " must be finite and >= 0, got " + format_number(types_[t].dipole));
    dipoles = dipoles || types_[t].dipole > 0.0;
    type_torques = type_torques || any_nonzero(types_[t].torque);
  }
  active_ = any_nonzero(torque_) || type_torques || (dipoles && any_nonzero(field_));
}

void TorqueField::check(std::size_t type_count) const {
  require(types_.empty() || types_.size() == type_count, ErrorCode::invalid_input, kWhere,
          "has " + std::to_string(types_.size()) + " type entries for " + std::to_string(type_count) +
              " particle types (expected one per type, or none)");
}

double TorqueField::compute(std::span<const double> orientations, std::span<const std::uint32_t> types,
                            std::span<double> torques) const {
  const std::size_t n = types.size();
  std::fill(torques.begin(), torques.end(), 0.0);
  if (!active_) return 0.0;
  double energy = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const TypeTorque none{};
    const TypeTorque& t = types_.empty() ? none : types_[types[i]];
    double* out = torques.data() + 3 * i;
    for (int c = 0; c < 3; ++c) out[c] = t.torque[c] + torque_[c];
    if (t.dipole == 0.0) continue;
    // mu u x E, energy -mu u . E (a point dipole in a uniform field).
    const auto u = quaternion::body_axis(std::span<const double, 4>(orientations.data() + 4 * i, 4));
    out[0] += t.dipole * (u[1] * field_[2] - u[2] * field_[1]);
    out[1] += t.dipole * (u[2] * field_[0] - u[0] * field_[2]);
    out[2] += t.dipole * (u[0] * field_[1] - u[1] * field_[0]);
    energy -= t.dipole * (u[0] * field_[0] + u[1] * field_[1] + u[2] * field_[2]);
  }
  return energy;
}

}  // namespace rpyfmm::bd
