// rpyfmm CLI — `rpyfmm laplace`: Laplace potentials, gradients and Hessians
// (kernel 1/r, no 1/(4 pi)) of charges at sources, evaluated at the sources
// or at separate targets. Under mpirun the FMM or the direct sums run across the ranks
// (laplace_across_ranks.hpp).
//
//   rpyfmm laplace --sources S.npy [--targets T.npy] --charges Q.npy
//                  (--direct | --tolerance E) --out R.npy [--threads N] [--json]
//
// R has shape (M,10), or (nd,M,10) when Q has shape (nd,N), with columns
// [pot, gx, gy, gz, hxx, hyy, hzz, hxy, hxz, hyz] (rpyfmm/fmm/direct.hpp).
#include <CLI/CLI.hpp>
#include <cstddef>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "array_io.hpp"
#include "cli_common.hpp"
#include "commands.hpp"
#include "laplace_across_ranks.hpp"
#include "laplace_problem.hpp"
#include "mpi_session.hpp"
#include "rpyfmm/core/cpu_features.hpp"
#include "rpyfmm/core/file_safety.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/fmm/direct.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"

namespace rpyfmm::cli {
namespace {

struct LaplaceArgs {
  std::string sources, targets, charges, out;
  bool direct = false;
  double tolerance = 0.0;  // FMM relative tolerance; 0 = not requested
  CommonOptions common;
  std::string io = "collective";  // --io, across MPI ranks
};

// ---- evaluation methods -------------------------------------------------
// Each fills `results` (nd x M x 10) and adds its stage timings to `stages`.
void evaluate_direct(const LaplaceProblem& p, std::vector<double>& results, StageTimes& /*stages*/) {
  fmm::laplace_direct(p.sources, p.charges, p.nd, p.targets, fmm::all_outputs, results);
}

// Adaptive plane-wave FMM (rpyfmm/fmm/laplace_fmm.hpp): plan once, evaluate all nd
// densities in one pass; its stage times go into the JSON line as "fmm_<stage>".
void evaluate_fmm(const LaplaceProblem& p, double tolerance, std::vector<double>& results, StageTimes& stages) {
  fmm::FmmOptions options;
  options.tolerance = tolerance;  // validated by the plan: [1e-15, 1e-1]
  fmm::LaplaceFmm plan(options);
  plan.set_points(p.sources, p.targets);
  plan.evaluate(p.charges, p.nd, fmm::all_outputs, results);
  for (const auto& [stage, seconds] : plan.last_timings()) stages["fmm_" + stage] = seconds;
  const auto st = plan.stats();
  stages["fmm_levels"] = st.levels;
  stages["fmm_leaves"] = static_cast<double>(st.leaves);
  stages["fmm_order"] = st.order;
}
// -------------------------------------------------------------------------

void run_laplace(const LaplaceArgs& args, bool fmm_requested) {
  require_distinct_files(
      std::vector<NamedPath>{{"--sources", args.sources}, {"--targets", args.targets}, {"--charges", args.charges}},
      std::vector<NamedPath>{{"--out", args.out}});
  apply_threads(args.common);
  require(args.direct != fmm_requested, ErrorCode::invalid_argument, "laplace",
          "choose exactly one method: --direct or --tolerance E");
  if (fmm_requested) ranges::require_in(ranges::kLaplaceTolerance, args.tolerance, "--tolerance", "tolerance");
  if (under_mpi()) {
    run_laplace_across_ranks(
        {args.sources, args.targets, args.charges, args.out, args.tolerance, args.direct, args.common.json, args.io});
    return;
  }
  StopWatch total;
  StopWatch watch;
  const LaplaceProblem p = read_laplace_problem(args.sources, args.targets, args.charges);
  StageTimes stages;
  stages["read"] = watch.seconds();

  std::vector<double> results(p.nd * p.m * fmm::result_width);
  watch.restart();
  if (args.direct) {
    evaluate_direct(p, results, stages);
  } else {
    evaluate_fmm(p, args.tolerance, results, stages);
  }
  stages["evaluate"] = watch.seconds();

  watch.restart();
  require_finite_output(results, "laplace");
  write_npy(args.out, laplace_output_shape(p), results);
  stages["write"] = watch.seconds();

  if (args.common.json) {
    JsonLine line;
    line.add("command", "laplace")
        .add("method", args.direct ? "direct" : "fmm")
        .add("n_sources", p.n)
        .add("n_targets", p.m)
        .add("at_sources", args.targets.empty())
        .add("nd", p.nd)
        .add("threads", active_threads())
        .add("simd", simd_level_name(simd_level()))
        .add("out", args.out)
        .add("pairs", static_cast<double>(p.n) * static_cast<double>(p.m) * static_cast<double>(p.nd))
        .add("seconds", stages)
        .add("total_seconds", total.seconds());
    if (!args.direct) line.add("tolerance", args.tolerance);
    std::cout << line.str() << '\n';
  }
}

}  // namespace

void register_laplace(CLI::App& app) {
  auto args = std::make_shared<LaplaceArgs>();
  CLI::App* cmd = app.add_subcommand(
      "laplace", "Laplace potential, gradient and Hessian (kernel 1/r) of charges: direct sums or FMM");
  cmd->add_option("--sources", args->sources, "source positions, (N,3) .npy or text")->required();
  cmd->add_option("--targets", args->targets, "target positions (M,3); default: at the sources, self pair skipped");
  cmd->add_option("--charges", args->charges, "charges (N,) or (nd,N)")->required();
  auto* direct = cmd->add_flag("--direct", args->direct, "exact O(N M) direct sums");
  const RenamedOption tolerance =
      add_renamed_option(*cmd, "--tolerance", "--eps", args->tolerance,
                         "FMM with relative tolerance E, in " + ranges::kLaplaceTolerance.str());
  direct->excludes(tolerance.option);
  direct->excludes(tolerance.deprecated);
  cmd->add_option("--out", args->out, "output .npy: (M,10) or (nd,M,10), columns pot,gx,gy,gz,hxx,hyy,hzz,hxy,hxz,hyz")
      ->required();
  add_common_options(*cmd, args->common);
  add_io_option(*cmd, args->io);
  cmd->callback([args, tolerance] {
    print_pending_warnings();
    run_laplace(*args, tolerance.given());
  });
}

}  // namespace rpyfmm::cli
