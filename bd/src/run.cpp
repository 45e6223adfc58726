#include "rpyfmm/bd/run.hpp"

#include <cmath>
#include <cstdio>
#include <sstream>

#include "rpyfmm/bd/checkpoint.hpp"
#include "rpyfmm/bd/output.hpp"
#include "rpyfmm/bd/particles.hpp"
#include "rpyfmm/core/file_safety.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::bd {

namespace {

struct Start {
  std::vector<double> positions, reference;
  std::vector<std::uint32_t> types;
  std::vector<Bond> bonds;
  std::uint64_t step = 0;
  std::uint64_t trajectory_bytes = 0, log_bytes = 0;
  std::uint64_t trajectory_hash = 0, log_hash = 0;
  bool restarted = false;
};

// The output directory: created (with missing parents) on construction; unless keep() is
// called, the destructor removes the directories it created, if they are empty, so a run
// refused at start-up leaves no trace.
class OutputDirectory {
 public:
  explicit OutputDirectory(const std::filesystem::path& dir) {
    std::error_code ec;
    for (auto p = std::filesystem::absolute(dir, ec).lexically_normal(); !ec && p != p.parent_path();
         p = p.parent_path()) {
      if (std::filesystem::exists(std::filesystem::symlink_status(p, ec))) break;
      created_.push_back(p);  // deepest first
    }
    std::filesystem::create_directories(dir, ec);
    if (ec) {
      remove_created();
      fail(ErrorCode::io_error, "output", "cannot create directory '" + dir.string() + "': " + ec.message());
    }
  }
  OutputDirectory(const OutputDirectory&) = delete;
  OutputDirectory& operator=(const OutputDirectory&) = delete;
  ~OutputDirectory() {
    if (!kept_) remove_created();
  }
  void keep() { kept_ = true; }

 private:
  void remove_created() {
    std::error_code ignored;
    for (const auto& p : created_) std::filesystem::remove(p, ignored);  // fails (harmlessly) if not empty
  }
  std::vector<std::filesystem::path> created_;
  bool kept_ = false;
};

// Checks, before anything is written, that no output of the run is an input (its config
// file, a particle file) or another output, and that the checkpoint can be replaced (so a
// long run does not fail at its first checkpoint). A restart's checkpoint is not an input
// here: it is replaced on purpose.
void check_run_files(const RunConfig& config, const RunSummary& sum) {
  std::vector<NamedPath> inputs, outputs;
  std::error_code ec;
  if (std::filesystem::is_regular_file(config.source, ec)) inputs.push_back({"config", config.source});
  if (config.particles.source == ParticleSpec::Source::file)
    inputs.push_back({"particles.file", config.particles.file});
  if (config.output.trajectory_every > 0) outputs.push_back({"output.trajectory", sum.trajectory});
  if (config.output.log_every > 0) outputs.push_back({"output.log", sum.log});
  outputs.push_back({"output.checkpoint", sum.checkpoint});
  require_distinct_files(inputs, outputs);
  require_regular_or_absent(sum.checkpoint);
}

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

RunSummary execute(const RunConfig& config, Start start, const RunOptions& options) {
  const std::uint64_t total = options.steps.value_or(config.steps);
  const OutputSpec& out = config.output;
  const auto dir = options.out_dir.value_or(out.dir);

  // Everything that can refuse the run comes before any file or directory is created.
  ForceField forces = make_force_field(config);
  forces.add_bonds(start.bonds);
  const std::size_t n = start.types.size();
  Integrator bd(rpy::make_mobility(config.mobility, n), forces, config.integrator, start.positions, start.types,
                config.neighbours, start.step);

  RunSummary sum;
  sum.particles = n;
  sum.mobility = bd.mobility().name();
  sum.first_step = start.step;
  sum.out_dir = dir;
  sum.trajectory = dir / out.trajectory;
  sum.log = dir / out.log;
  sum.checkpoint = dir / out.checkpoint;
  check_run_files(config, sum);

  // New files stay temporaries and reopened ones keep their tail until commit(): the run
  // has then started (a step succeeded, or a checkpoint is due). Before that, a refusal
  // removes what was created and changes nothing else.
  OutputDirectory made(dir);
  AppendFile traj, log;
  if (out.trajectory_every > 0) {
    if (start.restarted)
      traj.reopen(sum.trajectory, start.trajectory_bytes, start.trajectory_hash);
    else
      traj.create(sum.trajectory);
  }
  if (out.log_every > 0) {
    if (start.restarted)
      log.reopen(sum.log, start.log_bytes, start.log_hash);
    else
      log.create(sum.log);
    if (!start.restarted) log.write(csv_log_header(config.integrator.keep_split_displacements));
  }
  auto commit = [&]() {
    traj.publish();
    log.publish();
    made.keep();
  };
  auto save_checkpoint = [&]() {
    commit();
    Checkpoint c;
    c.step = bd.step_count();
    c.seed = config.integrator.seed;
    c.dt = config.integrator.dt;
    c.positions.assign(bd.positions().begin(), bd.positions().end());
    c.reference_positions = start.reference;
    c.types = start.types;
    c.trajectory_bytes = traj.bytes();
    c.trajectory_hash = traj.hash();
    c.log_bytes = log.bytes();
    c.log_hash = log.hash();
    c.config = config.text;
    write_checkpoint(sum.checkpoint, c);
  };

  // Interval statistics for the log.
  IntegratorTotals last = bd.totals();
  std::uint64_t last_log_step = bd.step_count();
  std::array<double, 3> last_centre{};
  auto centre = [&]() {
    std::array<double, 3> c{0, 0, 0};
    for (std::size_t i = 0; i < n; ++i)
      for (int d = 0; d < 3; ++d) c[d] += bd.positions()[3 * i + d];
    for (double& v : c) v /= static_cast<double>(n);
    return c;
  };
  last_centre = centre();
  double output_seconds = 0.0;
  double interval_output = 0.0;
  // integrator.split_displacements: rms of M F dt and of the Brownian part over the interval.
  const bool split = config.integrator.keep_split_displacements;
  double det2 = 0.0, brown2 = 0.0;
  std::uint64_t split_steps = 0;

  auto write_records = [&](bool first) {
    StopWatch w;
    const std::uint64_t s = bd.step_count();
    if (out.trajectory_every > 0 && s % out.trajectory_every == 0)
      traj.write(xyz_frame(bd.positions(), bd.types(), forces.types(), config.geometry, s, bd.time()));
    if (out.log_every > 0 && (s % out.log_every == 0 || s == total)) {
      double md = 0, msd = 0;
      for (std::size_t i = 0; i < n; ++i) {
        double d2 = 0;
        for (int c = 0; c < 3; ++c) d2 += std::pow(bd.positions()[3 * i + c] - start.reference[3 * i + c], 2);
        md += std::sqrt(d2);
        msd += d2;
      }
      md /= static_cast<double>(n);
      msd /= static_cast<double>(n);
      const auto cnow = centre();
      const double elapsed = static_cast<double>(s - last_log_step) * config.integrator.dt;
      const auto& t = bd.totals();
      const double steps = first ? 1.0 : std::max<double>(1.0, static_cast<double>(t.steps - last.steps));
      std::ostringstream row;
      row.precision(10);
      row << s << ',' << bd.time() << ',' << md << ',' << msd;
      for (int c = 0; c < 3; ++c) row << ',' << (elapsed > 0 ? (cnow[c] - last_centre[c]) / elapsed : 0.0);
      row << ',' << bd.last_report().potential_energy << ','
          << static_cast<double>(t.sqrt_iterations - last.sqrt_iterations) / steps << ','
          << static_cast<double>(t.mobility_products - last.mobility_products) / steps << ','
          << bd.neighbour_rebuilds();
      for (const char* part : {"neighbours", "forces", "plan", "drift", "sqrt", "update"})
        row << ',' << t.seconds.at(part) - last.seconds.at(part);
      row << ',' << interval_output;
      if (split) {
        const double norm = static_cast<double>(std::max<std::uint64_t>(split_steps, 1)) * static_cast<double>(n);
        row << ',' << std::sqrt(det2 / norm) << ',' << std::sqrt(brown2 / norm);
        det2 = brown2 = 0.0;
        split_steps = 0;
      }
      row << '\n';
      log.write(row.str());
      last = t;
      last_log_step = s;
      last_centre = cnow;
      interval_output = 0.0;
    }
    const double sec = w.seconds();
    output_seconds += sec;
    interval_output += sec;
  };

  if (!start.restarted) write_records(true);
  StopWatch wall;
  double last_progress = -1.0;
  while (bd.step_count() < total) {
    try {
      bd.step();
      if (split) {
        for (double d : bd.deterministic_displacement()) det2 += d * d;
        for (double d : bd.brownian_displacement()) brown2 += d * d;
        ++split_steps;
      }
    } catch (const Error& e) {
      const bool fresh_start = !start.restarted && bd.step_count() == 0;
      if (fresh_start && e.code() != ErrorCode::numerical_failure) throw;  // bad initial state: nothing to save
      save_checkpoint();
      throw Error(e.code(), std::string(e.what()) + "; last good state (step " + std::to_string(bd.step_count()) +
                                ") saved to '" + sum.checkpoint.string() + "'");
    }
    commit();
    write_records(false);
    const std::uint64_t s = bd.step_count();
    if (out.checkpoint_every > 0 && s % out.checkpoint_every == 0 && s != total) save_checkpoint();
    if (options.progress) {
      const double t = wall.seconds();
      if (t - last_progress >= 0.5 || s == total) {
        last_progress = t;
        const double rate = static_cast<double>(s - start.step) / std::max(t, 1e-9);
        const double eta = static_cast<double>(total - s) / std::max(rate, 1e-12);
        *options.progress << "\rstep " << s << "/" << total << "  " << fmt("%.3g", rate) << " steps/s  ETA "
                          << fmt("%.0f", eta) << " s   " << std::flush;
      }
    }
  }
  if (options.progress) *options.progress << "\n";
  save_checkpoint();
  sum.last_step = bd.step_count();
  sum.wall_seconds = wall.seconds();
  const auto& t = bd.totals();
  sum.steps_per_second = t.steps > 0 ? static_cast<double>(t.steps) / sum.wall_seconds : 0.0;
  sum.neighbour_rebuilds = bd.neighbour_rebuilds();
  const double steps = std::max<double>(1.0, static_cast<double>(t.steps));
  sum.mean_sqrt_iterations = static_cast<double>(t.sqrt_iterations) / steps;
  sum.mean_mobility_products = static_cast<double>(t.mobility_products) / steps;
  sum.preconditioner_blocks = bd.last_report().preconditioner_blocks;
  sum.seconds = t.seconds;
  sum.seconds["output"] = output_seconds;
  return sum;
}

}  // namespace

RunSummary run_bd(const RunConfig& config, const RunOptions& options) {
  ForceField forces = make_force_field(config);
  InitialState init = make_particles(config, forces);
  Start s;
  s.positions = init.positions;
  s.reference = init.positions;
  s.types = std::move(init.types);
  s.bonds = std::move(init.bonds);
  return execute(config, std::move(s), options);
}

RunSummary restart_bd(const std::filesystem::path& path, const RunOptions& options) {
  const Checkpoint c = read_checkpoint(path);
  std::string source = path.string();
  source.append(" (embedded config)");
  const RunConfig config = parse_config(c.config, source);
  if (c.seed != config.integrator.seed || c.dt != config.integrator.dt)
    fail(ErrorCode::io_error, "restart", source + ": seed/dt disagree with the checkpoint header");
  Start s;
  s.positions = c.positions;
  s.reference = c.reference_positions;
  s.types = c.types;
  s.step = c.step;
  s.trajectory_bytes = c.trajectory_bytes;
  s.log_bytes = c.log_bytes;
  s.trajectory_hash = c.trajectory_hash;
  s.log_hash = c.log_hash;
  s.restarted = true;
  RunOptions opts = options;  // outputs continue next to the checkpoint unless redirected
  if (!opts.out_dir) opts.out_dir = path.has_parent_path() ? path.parent_path() : std::filesystem::path(".");
  if (config.particles.source == ParticleSpec::Source::chains) {  // bonds are regenerated (deterministic)
    ForceField ff = make_force_field(config);
    s.bonds = make_particles(config, ff).bonds;
  }
  return execute(config, std::move(s), opts);
}

}  // namespace rpyfmm::bd
