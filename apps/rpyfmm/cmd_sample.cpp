// rpyfmm CLI — `rpyfmm sample` (to be registered by its owner).
#include "commands.hpp"

namespace rpyfmm::cli {
void register_sample(CLI::App& /*app*/) {}
}  // namespace rpyfmm::cli
