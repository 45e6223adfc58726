// rpyfmm CLI — what `rigid-bd` does alike on one process and across MPI ranks (rigid_bd_run.hpp).
#include "rigid_bd_run.hpp"

#include <algorithm>

#include "array_io.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::cli {

BodyState initial_state(const std::string& restart, const std::vector<double>& reference, std::size_t m) {
  BodyState state{reference, {}};
  if (restart.empty()) return state;
  const Array old = read_array(restart);
  require(old.shape.size() == 3 && old.shape[1] == m && old.shape[2] == 7 && old.shape[0] >= 1,
          ErrorCode::invalid_input, "--restart",
          "expected a trajectory of shape (frames, " + std::to_string(m) + ", 7) from rpyfmm rigid-bd");
  const std::size_t last = (old.shape[0] - 1) * m * 7;
  for (std::size_t k = 0; k < m; ++k) {
    for (std::size_t c = 0; c < 3; ++c) state.positions[3 * k + c] = old.data[last + 7 * k + c];
    for (std::size_t c = 0; c < 4; ++c) state.orientations.push_back(old.data[last + 7 * k + 3 + c]);
  }
  return state;
}

bd::BodyForceFunction constant_load(const std::array<double, 6>& load) {
  if (std::none_of(load.begin(), load.end(), [](double v) { return v != 0.0; })) return {};
  return [load](const bd::RigidBodyState&, std::span<double> w) {
    for (std::size_t k = 0; k < w.size(); k += 6)
      for (std::size_t c = 0; c < 6; ++c) w[k + c] = load[c];
  };
}

}  // namespace rpyfmm::cli
