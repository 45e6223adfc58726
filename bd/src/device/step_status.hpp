// rpyfmm::bd::device — what a step found, in store_min slots (atomics.hpp) that the stages fill
// and the host reads once per step: the lowest particle with an overlapping hard pair, the
// lowest broken bond, the lowest particle refused by the blow-up guard, and the lowest particle
// beyond skin/2 of its position at the last build (the next step's rebuild test).
#pragma once

#include <cstdint>

#include "atomics.hpp"

namespace rpyfmm::bd::device {

struct StepStatus {
  std::uint64_t bad_pair = kNone;
  std::uint64_t bad_bond = kNone;
  std::uint64_t bad_move = kNone;
  std::uint64_t moved = kNone;
};

/// Throws rpyfmm::Error for the first failure of `status` at step `step`, in the CPU engine's
/// order: an overlap or a broken bond (invalid_input, from the forces), then a blow-up
/// (numerical_failure). Returns when the step is good.
void throw_if_failed(const StepStatus& status, std::uint64_t step);

}  // namespace rpyfmm::bd::device
