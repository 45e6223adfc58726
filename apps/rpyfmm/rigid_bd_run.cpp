// rpyfmm CLI — what `rigid-bd` does alike on one process and across MPI ranks (rigid_bd_run.hpp).
#include "rigid_bd_run.hpp"

#include <algorithm>

#include "array_io.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::cli {

void require_trajectory_shape(const std::vector<std::size_t>& shape, std::size_t m) {
  require(shape.size() == 3 && shape[1] == m && shape[2] == 7 && shape[0] >= 1, ErrorCode::invalid_input, "--restart",
          "expected a trajectory of shape (frames, " + std::to_string(m) + ", 7) from rpyfmm rigid-bd");
}

BodyState state_of_frame(std::span<const double> rows) {
  BodyState state;
  for (std::size_t k = 0; 7 * k < rows.size(); ++k) {
    state.positions.insert(state.positions.end(), rows.begin() + 7 * k, rows.begin() + 7 * k + 3);
    state.orientations.insert(state.orientations.end(), rows.begin() + 7 * k + 3, rows.begin() + 7 * k + 7);
  }
  return state;
}

BodyState initial_state(const std::string& restart, const std::vector<double>& reference, std::size_t m) {
  if (restart.empty()) return BodyState{reference, {}};
  const Array old = read_array(restart);
  require_trajectory_shape(old.shape, m);
  return state_of_frame(std::span<const double>(old.data).subspan((old.shape[0] - 1) * m * 7));
}

bd::BodyForceFunction constant_load(const std::array<double, 6>& load) {
  if (std::none_of(load.begin(), load.end(), [](double v) { return v != 0.0; })) return {};
  return [load](const bd::RigidBodyState&, std::span<double> w) {
    for (std::size_t k = 0; k < w.size(); k += 6)
      for (std::size_t c = 0; c < 6; ++c) w[k + c] = load[c];
  };
}

}  // namespace rpyfmm::cli
