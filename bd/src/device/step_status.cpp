#include "step_status.hpp"

#include <string>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::bd::device {

void throw_if_failed(const StepStatus& status, std::uint64_t step) {
  const std::string at = " at step " + std::to_string(step);
  if (status.bad_pair != kNone)
    fail(ErrorCode::invalid_input, "forces",
         "particle " + std::to_string(status.bad_pair) + " overlaps a neighbour" + at +
             ": closer than the minimum distance of its hard pair potential");
  if (status.bad_bond != kNone)
    fail(ErrorCode::invalid_input, "forces",
         "bond " + std::to_string(status.bad_bond) + at +
             " joins coincident particles or is stretched beyond its FENE maximum extension");
  if (status.bad_move != kNone)
    fail(ErrorCode::numerical_failure, "bd",
         "blow-up" + at + ": particle " + std::to_string(status.bad_move) +
             " would move more than max_displacement x its radius in one step (or not by a finite "
             "amount); reduce dt or check the forces. State kept at the last good step");
}

}  // namespace rpyfmm::bd::device
