// rpyfmm CLI — `rpyfmm laplace` (to be registered by its owner).
#include "commands.hpp"

namespace rpyfmm::cli {
void register_laplace(CLI::App& /*app*/) {}
}  // namespace rpyfmm::cli
