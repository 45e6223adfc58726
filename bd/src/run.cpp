#include "rpyfmm/bd/run.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <memory>
#include <optional>
#include <span>
#include <sstream>

#include "rpyfmm/bd/checkpoint.hpp"
#include "rpyfmm/bd/output.hpp"
#include "rpyfmm/bd/particles.hpp"
#include "rpyfmm/bd/quaternion.hpp"
#include "rpyfmm/bd/trajectory.hpp"
#include "rpyfmm/core/file_safety.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::bd {

namespace {

// Whether any particle is of a Langevin type (inertia set for its type; LangevinGroup's reading).
bool has_langevin_particles(std::span<const std::optional<LangevinParticle>> inertia,
                            std::span<const std::uint32_t> types) {
  return std::any_of(types.begin(), types.end(),
                     [&](std::uint32_t t) { return t < inertia.size() && inertia[t].has_value(); });
}

struct Start {
  std::vector<double> positions, reference;
  // rotation: orientations (4N; empty = identity), those at step 0 (4N), the summed rotation
  // vectors (3N); the last two are filled by Run when a run starts
  std::vector<double> orientations, reference_orientations, rotation_vectors;
  std::vector<double> velocities;  // Langevin types: 3N half-step velocities (empty: Maxwell at start)
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

/// Centre of the particles.
std::array<double, 3> centre_of(std::span<const double> x, std::size_t n) {
  std::array<double, 3> c{0, 0, 0};
  for (std::size_t i = 0; i < n; ++i)
    for (int d = 0; d < 3; ++d) c[d] += x[3 * i + d];
  for (double& v : c) v /= static_cast<double>(n);
  return c;
}

/// Rotational MSD (mean |sum of rotation vectors|^2) and orientation correlation (mean
/// u(t) . u(0), u the body z axis) of the particles (docs/theory/bd.md Sec. 7).
std::array<double, 2> rotation_moments(std::span<const double> orientations, const std::vector<double>& reference,
                                       const std::vector<double>& rotation_vectors, std::size_t n) {
  const auto [msd, correlation] = rotation_moment_sums(orientations, reference, rotation_vectors);
  return {msd / static_cast<double>(n), correlation / static_cast<double>(n)};
}

/// Mean displacement and mean squared displacement from the reference positions.
std::array<double, 2> displacement_moments(std::span<const double> x, const std::vector<double>& reference,
                                           std::size_t n) {
  double md = 0, msd = 0;
  for (std::size_t i = 0; i < n; ++i) {
    double d2 = 0;
    for (int c = 0; c < 3; ++c) d2 += std::pow(x[3 * i + c] - reference[3 * i + c], 2);
    md += std::sqrt(d2);
    msd += d2;
  }
  return {md / static_cast<double>(n), msd / static_cast<double>(n)};
}

ForceField run_force_field(const RunConfig& config, const std::vector<Bond>& bonds) {
  ForceField forces = make_force_field(config);
  forces.add_bonds(bonds);
  return forces;
}

/// The Integrator of a run from `start`: the config's options with the engine its mobility asks
/// for ([mobility] device = "cuda" with method = "none": the device engine, docs/gpu-bd.md) and
/// that engine's mobility operator.
Integrator run_integrator(const RunConfig& config, const RunOptions& options, const ForceField& forces,
                          const Start& start) {
  IntegratorOptions o = config.integrator;
  if (options.engine) {  // an engine the caller makes (across MPI ranks): the operator it applies is named
    o.engine = StepEngine::external;
    return Integrator(
        rpy::make_mobility(config.mobility, start.types.size()), forces, o, start.positions, start.types,
        config.neighbours, start.step,
        options.engine(config, forces, start.positions, start.types, start.orientations, start.velocities, start.step));
  }
  o.engine = step_engine_for(config.mobility, options.device_launcher);
  return Integrator(engine_mobility(config.mobility, o.engine, start.types.size()), forces, o, start.positions,
                    start.types, config.neighbours, start.step, start.orientations, start.velocities);
}

/// One run from `start`: the integrator, its output files and the statistics of the log rows.
/// Everything that can refuse the run (forces, operator, file names) is checked in the
/// constructor, before any file or directory is created.
class Run {
 public:
  Run(const RunConfig& config, Start start, const RunOptions& options)
      : config_(config),
        options_(options),
        start_(std::move(start)),
        total_(options.steps.value_or(config.steps)),
        forces_(run_force_field(config, start_.bonds)),
        n_(start_.types.size()),
        langevin_(has_langevin_particles(config.integrator.inertia, start_.types)),
        bd_(run_integrator(config, options, forces_, start_)) {
    if (config.integrator.rotation && !start_.restarted) {  // the reference state of the log's moments
      start_.reference_orientations.assign(bd_.orientations().begin(), bd_.orientations().end());
      start_.rotation_vectors.assign(3 * n_, 0.0);
    }
    const auto dir = options.out_dir.value_or(config.output.dir);
    require(!dir.empty(), ErrorCode::invalid_argument, "run_bd", "the output directory (out_dir) is empty");
    sum_.particles = n_;
    sum_.mobility = bd_.mobility().name();
    sum_.engine = options.engine ? options.engine_name : to_string(bd_.options().engine);
    sum_.first_step = start_.step;
    sum_.out_dir = dir;
    sum_.trajectory = dir / config.output.trajectory;
    sum_.log = dir / config.output.log;
    sum_.checkpoint = dir / config.output.checkpoint;
    on_writer([&] { check_run_files(config, sum_); });
  }

  RunSummary execute() {
    open_outputs();
    last_.totals = bd_.totals();
    last_.step = bd_.step_count();
    // Read on every process (the read may be collective), used on the one that writes (an engine
    // across processes may gather the positions there alone, Stepper::positions).
    const auto x = bd_.positions();
    if (options_.writes_files) last_.centre = centre_of(x, n_);
    if (!start_.restarted) write_records(true);
    StopWatch wall;
    double last_progress = -1.0;
    while (bd_.step_count() < total_) {
      step();
      commit();
      write_records(false);
      const std::uint64_t s = bd_.step_count();
      if (config_.output.checkpoint_every > 0 && s % config_.output.checkpoint_every == 0 && s != total_)
        save_checkpoint();
      if (options_.progress) report_progress(wall.seconds(), last_progress);
    }
    if (options_.progress) *options_.progress << "\n";
    save_checkpoint();
    return summary(wall.seconds());
  }

 private:
  // What changed since the previous log row.
  struct Interval {
    IntegratorTotals totals;
    std::uint64_t step = 0;
    std::array<double, 3> centre{};
    double output_seconds = 0.0;
    double det2 = 0.0, brown2 = 0.0;  // split displacements: sums of squares over the interval
    std::uint64_t split_steps = 0;
  };

  // New files stay temporaries and reopened ones keep their tail until commit(): the run
  // has then started (a step succeeded, or a checkpoint is due). Before that, a refusal
  // removes what was created and changes nothing else.
  void open_outputs() {
    on_writer([&] { open_files(); });
  }

  // Runs `write` on the process that writes the files; across processes, every one then learns
  // whether it failed (RunOptions::agree), so that all stop together.
  template <class Write>
  void on_writer(Write&& write) const {
    std::optional<Error> problem;
    if (options_.writes_files) {
      try {
        write();
      } catch (const Error& e) {
        if (!options_.agree) throw;
        problem = e;
      }
    }
    if (options_.agree) options_.agree(problem);
  }

  void open_files() {
    made_.emplace(sum_.out_dir);
    if (config_.output.trajectory_every > 0) {
      if (start_.restarted)
        traj_.reopen(sum_.trajectory, start_.trajectory_bytes, start_.trajectory_hash);
      else
        traj_.create(sum_.trajectory);
    }
    if (config_.output.log_every > 0) {
      if (start_.restarted)
        log_.reopen(sum_.log, start_.log_bytes, start_.log_hash);
      else
        log_.create(sum_.log);
      if (!start_.restarted)
        log_.write(csv_log_header(config_.integrator.keep_split_displacements, config_.integrator.rotation, langevin_,
                                  config_.integrator.sac.enabled));
    }
  }

  void commit() {
    on_writer([&] {
      traj_.publish();
      log_.publish();
      made_->keep();
    });
  }

  void save_checkpoint() {
    commit();
    Checkpoint c;  // on every process: reading the engine's state may be collective
    c.step = bd_.step_count();
    c.seed = config_.integrator.seed;
    c.dt = config_.integrator.dt;
    c.positions.assign(bd_.positions().begin(), bd_.positions().end());
    c.reference_positions = start_.reference;
    c.types = start_.types;
    if (config_.integrator.rotation) {
      c.orientations.assign(bd_.orientations().begin(), bd_.orientations().end());
      c.reference_orientations = start_.reference_orientations;
      c.rotation_vectors = start_.rotation_vectors;
    }
    const auto v = bd_.velocities();  // on every process (the read may be collective), used on the writer
    c.velocities.assign(v.begin(), v.end());
    on_writer([&] {
      traj_.flush();  // the frames the checkpoint counts are in the file before it names them
      c.trajectory_bytes = traj_.length();
      c.trajectory_hash = traj_.hash();
      c.log_bytes = log_.bytes();
      c.log_hash = log_.hash();
      c.config = config_.text;
      write_checkpoint(sum_.checkpoint, c);
    });
  }

  /// One step; on failure after the run has started, the last good state is saved first.
  void step() {
    try {
      bd_.step();
      const auto phi = bd_.last_rotations();  // empty without rotation
      for (std::size_t k = 0; k < phi.size(); ++k) start_.rotation_vectors[k] += phi[k];
      if (config_.integrator.keep_split_displacements) {
        for (double d : bd_.deterministic_displacement()) last_.det2 += d * d;
        for (double d : bd_.brownian_displacement()) last_.brown2 += d * d;
        ++last_.split_steps;
      }
    } catch (const Error& e) {
      const bool fresh_start = !start_.restarted && bd_.step_count() == 0;
      if (fresh_start && e.code() != ErrorCode::numerical_failure) throw;  // bad initial state: nothing to save
      save_checkpoint();
      throw Error(e.code(), std::string(e.what()) + "; last good state (step " + std::to_string(bd_.step_count()) +
                                ") saved to '" + sum_.checkpoint.string() + "'");
    }
  }

  /// The trajectory frame and the log row due at the current step.
  void write_records(bool first) {
    StopWatch w;
    const OutputSpec& out = config_.output;
    const std::uint64_t s = bd_.step_count();
    if (out.trajectory_every > 0 && s % out.trajectory_every == 0) {
      const auto x = bd_.positions();  // on every process: the reads may be collective
      const auto q = bd_.orientations();
      const auto complex_ids = bd_.complex_ids();
      on_writer([&] { traj_.write(x, bd_.types(), forces_.types(), config_.geometry, s, bd_.time(), q, complex_ids); });
    }
    if (out.log_every > 0 && (s % out.log_every == 0 || s == total_)) write_log_row(first);
    const double sec = w.seconds();
    output_seconds_ += sec;
    last_.output_seconds += sec;
  }

  void write_log_row(bool first) {
    const std::uint64_t s = bd_.step_count();
    // The positions are read on every process (the read may be collective) and used on the one
    // that writes (an engine across processes may gather them there alone, Stepper::positions).
    const auto x = bd_.positions();
    std::array<double, 2> moments{};
    std::array<double, 3> cnow{};
    if (options_.writes_files) {
      moments = displacement_moments(x, start_.reference, n_);
      cnow = centre_of(x, n_);
    }
    const auto [md, msd] = moments;
    const double elapsed = static_cast<double>(s - last_.step) * config_.integrator.dt;
    const IntegratorTotals t = bd_.totals();
    const double steps = first ? 1.0 : std::max<double>(1.0, static_cast<double>(t.steps - last_.totals.steps));
    std::ostringstream row;
    row.precision(10);
    row << s << ',' << bd_.time() << ',' << md << ',' << msd;
    for (int c = 0; c < 3; ++c) row << ',' << (elapsed > 0 ? (cnow[c] - last_.centre[c]) / elapsed : 0.0);
    row << ',' << bd_.last_report().potential_energy << ','
        << static_cast<double>(t.sqrt_iterations - last_.totals.sqrt_iterations) / steps << ','
        << static_cast<double>(t.mobility_products - last_.totals.mobility_products) / steps << ','
        << bd_.neighbour_rebuilds();
    for (const char* part : {"neighbours", "forces", "plan", "drift", "sqrt", "update"})
      row << ',' << t.seconds.at(part) - last_.totals.seconds.at(part);
    row << ',' << last_.output_seconds;
    if (config_.integrator.keep_split_displacements) {  // rms of M F dt and of the Brownian part
      const double norm = static_cast<double>(std::max<std::uint64_t>(last_.split_steps, 1)) * static_cast<double>(n_);
      row << ',' << std::sqrt(last_.det2 / norm) << ',' << std::sqrt(last_.brown2 / norm);
    }
    if (config_.integrator.rotation) {
      const auto q = bd_.orientations();  // on every process (the read may be collective), used on the writer
      const auto [rmsd, correlation] =
          options_.writes_files ? rotation_moments(q, start_.reference_orientations, start_.rotation_vectors, n_)
                                : std::array<double, 2>{};
      row << ',' << rmsd << ',' << correlation;
    }
    if (langevin_) row << ',' << bd_.kinetic_temperature();  // on every process (may be collective)
    if (config_.integrator.sac.enabled) {  // on every process (may be collective); Complexes::mean_adsorbed()
      const auto [complexes, adsorbed] = bd_.complex_counts();
      row << ',' << complexes << ','
          << (complexes == 0 ? 0.0 : static_cast<double>(adsorbed) / static_cast<double>(complexes));
    }
    row << '\n';
    on_writer([&] { log_.write(row.str()); });
    last_ = Interval{t, s, cnow};
  }

  void report_progress(double seconds, double& last_progress) {
    const std::uint64_t s = bd_.step_count();
    if (seconds - last_progress < 0.5 && s != total_) return;
    last_progress = seconds;
    const double rate = static_cast<double>(s - start_.step) / std::max(seconds, 1e-9);
    const double eta = static_cast<double>(total_ - s) / std::max(rate, 1e-12);
    *options_.progress << "\rstep " << s << "/" << total_ << "  " << fmt("%.3g", rate) << " steps/s  ETA "
                       << fmt("%.0f", eta) << " s   " << std::flush;
  }

  RunSummary summary(double wall_seconds) {
    RunSummary sum = sum_;
    sum.last_step = bd_.step_count();
    sum.wall_seconds = wall_seconds;
    const IntegratorTotals t = bd_.totals();
    sum.steps_per_second = t.steps > 0 ? static_cast<double>(t.steps) / sum.wall_seconds : 0.0;
    sum.neighbour_rebuilds = bd_.neighbour_rebuilds();
    const double steps = std::max<double>(1.0, static_cast<double>(t.steps));
    sum.mean_sqrt_iterations = static_cast<double>(t.sqrt_iterations) / steps;
    sum.mean_mobility_products = static_cast<double>(t.mobility_products) / steps;
    sum.preconditioner_blocks = bd_.last_report().preconditioner_blocks;
    sum.seconds = t.seconds;
    sum.seconds["output"] = output_seconds_;
    return sum;
  }

  const RunConfig& config_;
  const RunOptions& options_;
  Start start_;
  std::uint64_t total_;
  ForceField forces_;
  std::size_t n_;
  bool langevin_;  // some particle is of a Langevin type: velocities, the log's kinetic temperature
  Integrator bd_;
  RunSummary sum_;
  std::optional<OutputDirectory> made_;  // before the files: they are removed first on failure
  TrajectoryFile traj_{config_.output.format};
  AppendFile log_;
  Interval last_;
  double output_seconds_ = 0.0;
};

RunSummary execute(const RunConfig& config, Start start, const RunOptions& options) {
  return Run(config, std::move(start), options).execute();
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
  s.orientations = std::move(init.orientations);
  return execute(config, std::move(s), options);
}

RunSummary restart_bd(const std::filesystem::path& path, const RunOptions& options) {
  const Checkpoint c = read_checkpoint(path);
  std::string source = path.string();
  source.append(" (embedded config)");
  const RunConfig config = parse_config(c.config, source);
  if (c.seed != config.integrator.seed || c.dt != config.integrator.dt)
    fail(ErrorCode::io_error, "restart", source + ": seed/dt disagree with the checkpoint header");
  if (config.integrator.rotation == c.orientations.empty())
    fail(ErrorCode::io_error, "restart", source + ": system.rotation disagrees with the checkpoint's orientations");
  if (has_langevin_particles(config.integrator.inertia, c.types) == c.velocities.empty())
    fail(ErrorCode::io_error, "restart", source + ": the Langevin types disagree with the checkpoint's velocities");
  Start s;
  s.positions = c.positions;
  s.reference = c.reference_positions;
  s.types = c.types;
  s.orientations = c.orientations;
  s.reference_orientations = c.reference_orientations;
  s.rotation_vectors = c.rotation_vectors;
  s.velocities = c.velocities;
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
