// rpyfmm — command-line tool over the library.
//
// Exit codes: 0 success, 2 bad input or failure (one line on stderr naming
// the problem; no output file is left behind). Under an MPI launcher (mpi_session.hpp) every rank
// exits alike and rank 0 alone prints.
#include <CLI/CLI.hpp>
#include <exception>
#include <iostream>
#include <new>
#include <ostream>
#include <string>

#include "cli_common.hpp"
#include "commands.hpp"
#include "mpi_session.hpp"
#include "rpyfmm/core/cpu_features.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/fmm/version.hpp"

namespace {

// The commands that run across MPI ranks; the others refuse a run on more than one.
bool runs_across_ranks(const std::string& command) {
  return command == "laplace" || command == "mobility" || command == "sample" || command == "bd" ||
         command == "rigid" || command == "rigid-bd";
}

// Errors are printed once: by rank 0 (every rank fails alike, rpyfmm::mpi::Communicator).
std::ostream& error_stream() {
  static std::ostream discard(nullptr);
  return rpyfmm::cli::mpi_rank() == 0 ? std::cerr : discard;
}

}  // namespace

int main(int argc, char** argv) {
  const rpyfmm::cli::MpiSessionEnd mpi_session_end;  // MPI_Finalize last, if MPI was started
  CLI::App app{"rpyfmm: fast Rotne-Prager-Yamakawa hydrodynamics for Brownian dynamics"};
  app.set_version_flag("--version", rpyfmm::version());
  app.require_subcommand(0, 1);
  rpyfmm::cli::register_laplace(app);
  rpyfmm::cli::register_mobility(app);
  rpyfmm::cli::register_sample(app);
  rpyfmm::cli::register_bd(app);
  rpyfmm::cli::register_rigid(app);
  rpyfmm::cli::register_rigid_bd(app);
  rpyfmm::cli::add_mpi_flag(app);
  rpyfmm::cli::refuse_empty_values(app);
  // After parsing (--mpi known), before the command runs: MPI starts where asked for.
  app.parse_complete_callback([&app] {
    if (!rpyfmm::cli::under_mpi()) return;
    for (const CLI::App* command : app.get_subcommands())
      if (!runs_across_ranks(command->get_name())) rpyfmm::cli::require_one_rank(command->get_name());
  });
  try {
    rpyfmm::require_valid_simd_environment();  // RPYFMM_SIMD: a typo is an error, not a warning
    app.parse(argc, argv);
    if (app.get_subcommands().empty()) {
      std::cout << app.help();
      return 0;
    }
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::Success& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    error_stream() << "rpyfmm: error: " << e.what() << " (see --help)\n";
    return 2;
  } catch (const rpyfmm::Error& e) {
    error_stream() << "rpyfmm: error: " << e.what() << "\n";
    return 2;
  } catch (const std::bad_alloc&) {
    // Readers name their input when memory runs out; this is for the sizes computations ask for.
    error_stream() << "rpyfmm: error: out of memory: the problem is too large for this machine (fewer particles, "
                      "a smaller --max-iterations or --preconditioner-block)\n";
    return 2;
  } catch (const std::exception& e) {
    error_stream() << "rpyfmm: error: " << e.what() << "\n";
    return 2;
  }
  return 0;
}
