// rpyfmm — command-line tool over the library.
//
// Exit codes: 0 success, 2 bad input or failure (one line on stderr naming
// the problem; no output file is left behind).
#include <CLI/CLI.hpp>
#include <exception>
#include <iostream>
#include <new>

#include "commands.hpp"
#include "rpyfmm/core/cpu_features.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/fmm/version.hpp"

int main(int argc, char** argv) {
  CLI::App app{"rpyfmm: fast Rotne-Prager-Yamakawa hydrodynamics for Brownian dynamics"};
  app.set_version_flag("--version", rpyfmm::version());
  app.require_subcommand(0, 1);
  rpyfmm::cli::register_laplace(app);
  rpyfmm::cli::register_mobility(app);
  rpyfmm::cli::register_sample(app);
  rpyfmm::cli::register_bd(app);
  rpyfmm::cli::register_rigid(app);
  rpyfmm::cli::register_rigid_bd(app);
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
    std::cerr << "rpyfmm: error: " << e.what() << " (see --help)\n";
    return 2;
  } catch (const rpyfmm::Error& e) {
    std::cerr << "rpyfmm: error: " << e.what() << "\n";
    return 2;
  } catch (const std::bad_alloc&) {
    // Readers name their input when memory runs out; this is for the sizes computations ask for.
    std::cerr << "rpyfmm: error: out of memory: the problem is too large for this machine (fewer particles, "
                 "a smaller --max-iterations or --preconditioner-block)\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "rpyfmm: error: " << e.what() << "\n";
    return 2;
  }
  return 0;
}
