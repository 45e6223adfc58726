// Test helper for bitwise restarts: one config run twice, uninterrupted into `whole`, and stopped
// after `stop` steps into `split`, then restarted there from its checkpoint to the end.
#pragma once

#include <cstdint>
#include <filesystem>

#include "rpyfmm/bd/run.hpp"

namespace bdtest {

/// Returns the restarted run's summary.
inline rpyfmm::bd::RunSummary run_whole_and_restarted(const rpyfmm::bd::RunConfig& config,
                                                      const std::filesystem::path& whole,
                                                      const std::filesystem::path& split, std::uint64_t stop) {
  rpyfmm::bd::RunOptions full, part;
  full.out_dir = whole;
  part.out_dir = split;
  part.steps = stop;
  (void)rpyfmm::bd::run_bd(config, full);
  (void)rpyfmm::bd::run_bd(config, part);
  return rpyfmm::bd::restart_bd(split / "checkpoint.bin");
}

}  // namespace bdtest
