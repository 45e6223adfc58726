// rpyfmm CLI — `rpyfmm bd` (to be registered by its owner).
#include "commands.hpp"

namespace rpyfmm::cli {
void register_bd(CLI::App& /*app*/) {}
}  // namespace rpyfmm::cli
