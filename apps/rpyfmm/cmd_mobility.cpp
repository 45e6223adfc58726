// rpyfmm CLI — `rpyfmm mobility` (to be registered by its owner).
#include "commands.hpp"

namespace rpyfmm::cli {
void register_mobility(CLI::App& /*app*/) {}
}  // namespace rpyfmm::cli
