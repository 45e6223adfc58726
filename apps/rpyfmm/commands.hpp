// rpyfmm CLI — one registration function per subcommand (one file each).
#pragma once

namespace CLI {
class App;
}

namespace rpyfmm::cli {
void register_laplace(CLI::App& app);   // cmd_laplace.cpp: direct sums and the FMM
void register_mobility(CLI::App& app);  // cmd_mobility.cpp: U = M F
void register_sample(CLI::App& app);    // cmd_sample.cpp: M^{1/2} z
void register_bd(CLI::App& app);        // cmd_bd.cpp: Brownian dynamics with HI
void register_rigid(CLI::App& app);     // cmd_rigid.cpp: rigid bodies of beads
void register_rigid_bd(CLI::App& app);  // cmd_rigid_bd.cpp: their Brownian dynamics
}  // namespace rpyfmm::cli
