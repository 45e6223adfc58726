// rpyfmm CLI — what `rigid-bd` does alike on one process and across MPI ranks: the state to start
// from (identity orientations, or the last frame of --restart), the constant load of --body-force
// and --body-torque, and which steps write a frame.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "rpyfmm/bd/rigid_dynamics.hpp"

namespace rpyfmm::cli {

/// The bodies' positions and orientations (3m and 4m) to start from.
struct BodyState {
  std::vector<double> positions, orientations;
};

/// `reference` with identity orientations (empty: the engine's default) where `restart` is empty,
/// otherwise the last frame of the trajectory `restart` (frames, m, 7) from rpyfmm rigid-bd;
/// rpyfmm::Error naming --restart on a file of another shape.
BodyState initial_state(const std::string& restart, const std::vector<double>& reference, std::size_t m);

/// initial_state's check of --restart's shape: (frames >= 1, m, 7); rpyfmm::Error naming --restart.
void require_trajectory_shape(const std::vector<std::size_t>& shape, std::size_t m);
/// The positions and orientations of a frame's rows (7 per body: q_x q_y q_z w x y z).
BodyState state_of_frame(std::span<const double> rows);

/// The same force F and torque T (load = F then T) on every body; none when both are zero.
bd::BodyForceFunction constant_load(const std::array<double, 6>& load);

/// Takes `steps` steps by step(), calling record() before the first, after each step whose number
/// (step_count()) is a multiple of `every` (0: none) and after the last.
template <class Step, class StepCount, class Record>
void step_and_record(std::uint64_t steps, std::uint64_t every, Step&& step, StepCount&& step_count, Record&& record) {
  if (every == 0) every = steps;
  record();
  for (std::uint64_t s = 1; s <= steps; ++s) {
    step();
    if (step_count() % every == 0 || s == steps) record();
  }
}

}  // namespace rpyfmm::cli
