// rpyfmm CLI — `rpyfmm rigid-bd` across MPI ranks (rigid_bd_across_ranks.hpp).
#include "rigid_bd_across_ranks.hpp"

#include <mpi.h>

#include <cstddef>
#include <cstdint>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "array_io.hpp"
#include "body_io.hpp"
#include "body_shares.hpp"
#include "cli_common.hpp"
#include "rank_shares.hpp"
#include "rigid_bd_run.hpp"
#include "rpyfmm/core/cpu_features.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/mpi/direct_operator.hpp"
#include "rpyfmm/mpi/fmm_rpy.hpp"
#include "rpyfmm/mpi/pse_operator.hpp"
#include "rpyfmm/mpi/rigid_dynamics.hpp"

namespace rpyfmm::cli {
namespace {

// This rank's bodies as the engine takes them: body-frame shapes (3 per bead), radii, body offsets
// from 0, and the state to start from (3 and 4 per body).
struct Start {
  std::vector<double> shape, radii, positions, orientations;
  std::vector<std::size_t> offsets;
};

// --restart's last frame, this rank's bodies' rows (initial_state's check and state).
BodyState restart_state(const std::string& restart, IoMode mode, BodiesShare& b, const mpi::Communicator& comm) {
  const std::size_t m = b.z.bodies();
  const ArrayShare last = read_body_rows(
      restart, mode, 7, false, [m](const auto& shape) { require_trajectory_shape(shape, m); },
      [m](const std::vector<std::size_t>& shape) { return (shape[0] - 1) * m * 7; }, b, b.scatter_seconds, comm);
  return state_of_frame(last.local);
}

// What the serial command builds from the files, on each rank's bodies (body_io.hpp): shapes
// relative to the reference points (default: centroids; minimum images in pse's --box), the state
// of --restart or the identity orientations. Each body's shape is computed alone, as in the serial
// command.
Start read_start(const RanksRigidBdArgs& args, IoMode mode, BodiesShare& b, const mpi::Communicator& comm) {
  b = read_bodies_share(args.bodies, mode, comm);
  std::vector<double> reference = b.local.reference;
  Start s;
  comm.run([&] { s.shape = body_frame_shape(args.box, b.local, reference); });
  BodyState state = args.restart.empty() ? BodyState{reference, {}} : restart_state(args.restart, mode, b, comm);
  s.positions = std::move(state.positions);
  s.orientations = std::move(state.orientations);
  if (s.orientations.empty())
    for (std::size_t k = 0; k < b.local.bodies(); ++k)
      s.orientations.insert(s.orientations.end(), {1.0, 0.0, 0.0, 0.0});
  s.radii = b.local.radii;
  s.offsets = b.local.offsets;
  return s;
}

// What a run leaves on this rank: its bodies' frames (7 values per body per frame), its final bead
// positions, the iteration totals and the stage times.
struct LocalRun {
  std::vector<double> frames, beads;
  std::size_t frame_count = 0;
  bd::RigidDynamicsTotals totals;
  std::uint64_t last_step = 0;
};

// --pair's field (the serial command's, of the first bead's radius) on the engine, on every rank.
void add_bead_pair(mpi::DistributedRigidBodyDynamics& sim, const RanksRigidBdArgs& args, double first_radius) {
  std::optional<bd::ForceField> field;
  sim.communicator().run([&] { field = bead_pair_field(args.pair, first_radius); });
  if (field) sim.set_bead_forces(std::move(*field));
}

template <class Operator>
LocalRun run_engine(Operator& op, const RanksRigidBdArgs& args, Start& local, double first_radius, StageTimes& stages) {
  StopWatch watch;
  mpi::DistributedRigidBodyDynamics sim(op, std::move(local.shape), std::move(local.radii), std::move(local.offsets),
                                        std::move(local.positions), std::move(local.orientations), args.options,
                                        constant_load(args.load));
  add_bead_pair(sim, args, first_radius);
  stages["setup"] = watch.seconds();
  watch.restart();
  LocalRun run;
  const auto record = [&] {
    const auto q = sim.local_positions();
    const auto quat = sim.local_orientations();
    for (std::size_t k = 0; k < sim.local_bodies(); ++k) {
      run.frames.insert(run.frames.end(), q.begin() + std::ptrdiff_t(3 * k), q.begin() + std::ptrdiff_t(3 * k + 3));
      run.frames.insert(run.frames.end(), quat.begin() + std::ptrdiff_t(4 * k),
                        quat.begin() + std::ptrdiff_t(4 * k + 4));
    }
    ++run.frame_count;
  };
  step_and_record(
      args.steps, args.every, [&] { sim.step(); }, [&] { return sim.step_count(); }, record);
  stages["run"] = watch.seconds();
  run.beads.assign(sim.local_bead_positions().begin(), sim.local_bead_positions().end());
  run.totals = sim.totals();
  run.last_step = sim.step_count();
  return run;
}

LocalRun run_across_ranks(const RanksRigidBdArgs& args, Start& local, double first_radius, StageTimes& stages) {
  if (args.method == "pse") {  // PseRpy's options but the tolerance, as the serial command's PseRpy
    mpi::DistributedPseRpy pse(MPI_COMM_WORLD, args.box, args.viscosity, {.tolerance = args.tolerance});
    return run_engine(pse, args, local, first_radius, stages);
  }
  if (args.method == "fmm") {
    mpi::DistributedFmmRpy fmm(MPI_COMM_WORLD, args.viscosity, {.tolerance = args.tolerance});
    return run_engine(fmm, args, local, first_radius, stages);
  }
  mpi::DistributedDirectRpy direct(MPI_COMM_WORLD, args.viscosity);
  return run_engine(direct, args, local, first_radius, stages);
}

// The trajectory (frames, m, 7) and the final beads (N,3), both checked first (the final beads also
// without --beads-out, as in the serial command), written by every rank (--io collective: each
// frame's rows of this rank's bodies) or by rank 0 after a gather (--io root), together (a failure
// leaves both targets as they were): the serial command's files.
void write_outputs(const RanksRigidBdArgs& args, const LocalRun& run, const BodyLayout& z, IoMode mode,
                   const mpi::Communicator& comm) {
  const std::size_t m = z.bodies(), per_frame = 7 * m;
  const Shares frame_shares = body_shares(z, 7, false);
  const std::size_t mine = frame_shares.count(comm.rank()), first = first_of_rows(z, 7, false, comm.rank());
  std::vector<NpyRun> frames;
  for (std::size_t f = 0; f < run.frame_count; ++f)
    frames.push_back({f * per_frame + first, std::span<const double>(run.frames).subspan(f * mine, mine)});
  const NpyRun beads{first_of_rows(z, 3, true, comm.rank()), run.beads};
  require_finite_result(frames, "rigid-bd (trajectory)", comm);
  require_finite_result({&beads, 1}, "rigid-bd (bead positions)", comm);
  std::vector<RowsFile> files{{args.out, {run.frame_count, m, 7}, frames, frame_shares, per_frame}};
  if (!args.beads_out.empty())
    files.push_back({args.beads_out, {z.beads(), 3}, {&beads, 1}, body_shares(z, 3, true), 3 * z.beads()});
  write_rows_together(files, mode, comm);
}

void report(const RanksRigidBdArgs& args, const BodyLayout& z, const LocalRun& run, const StageTimes& stages,
            double total_seconds, const mpi::Communicator& comm) {
  const StageTimes slowest_stages = slowest(stages, comm);  // collective
  const StageTimes slowest_steps = slowest(run.totals.seconds, comm);
  if (comm.rank() != 0) return;
  const auto steps = static_cast<double>(args.steps);
  const bd::RigidDynamicsTotals& t = run.totals;  // iterations: the same on every rank
  const double per_step = slowest_stages.at("run") / steps;
  if (!args.json) {
    std::cout << "rigid-bd: " << z.bodies() << " bodies, " << z.beads() << " beads on " << comm.size() << " ranks, "
              << args.steps << " steps in " << slowest_stages.at("run") << " s (" << per_step << " s/step; GMRES "
              << double(t.solve_iterations) / steps << " + " << double(t.drift_iterations) / steps << " drift, sampler "
              << double(t.sqrt_iterations) / steps << " iterations per step); " << run.frame_count << " frames -> "
              << args.out << '\n';
    return;
  }
  JsonLine line;
  line.add("command", "rigid-bd")
      .add("method", args.method)
      .add("drift", args.options.drift == bd::RigidDrift::none ? "none" : "rfd")
      .add("bodies", z.bodies())
      .add("beads", z.beads())
      .add("steps", static_cast<std::size_t>(args.steps))
      .add("last_step", static_cast<std::size_t>(run.last_step))
      .add("frames", run.frame_count)
      .add("dt", args.options.dt)
      .add("kT", args.options.kT)
      .add("solve_iterations_per_step", double(t.solve_iterations) / steps)
      .add("drift_iterations_per_step", double(t.drift_iterations) / steps)
      .add("sqrt_iterations_per_step", double(t.sqrt_iterations) / steps)
      .add("seconds_per_step", per_step)
      .add("ranks", comm.size())
      .add("threads", active_threads())
      .add("simd", simd_level_name(simd_level()))
      .add("out", args.out)
      .add("seconds", slowest_stages)
      .add("step_seconds", slowest_steps)
      .add("total_seconds", total_seconds);
  std::cout << line.str() << '\n';
}

}  // namespace

void run_rigid_bd_across_ranks(const RanksRigidBdArgs& args) {
  const mpi::Communicator comm(MPI_COMM_WORLD);
  StopWatch total;
  StageTimes stages;
  IoMode mode = IoMode::collective;
  comm.run([&] { mode = io_mode(args.io); });
  BodiesShare bodies;
  Start local = read_start(args, mode, bodies, comm);
  stages["read"] = total.seconds() - bodies.scatter_seconds;
  stages["distribute"] = bodies.scatter_seconds;
  const BodyLayout& z = bodies.z;
  // --pair's bead type: the first bead's radius (rank 0 always holds the first body).
  double first_radius = comm.rank() == 0 ? local.radii.front() : 0.0;
  mpi::check_mpi(MPI_Bcast(&first_radius, 1, MPI_DOUBLE, 0, comm.get()), "MPI_Bcast");
  bodies.local = BeadBodies{};  // the engine takes `local` from here on

  const LocalRun run = run_across_ranks(args, local, first_radius, stages);

  StopWatch watch;
  write_outputs(args, run, z, mode, comm);
  stages["write"] = watch.seconds();
  report(args, z, run, stages, total.seconds(), comm);
}

}  // namespace rpyfmm::cli
