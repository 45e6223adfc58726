// rpyfmm Python bindings — Brownian dynamics (bd/include/rpyfmm/bd/*.hpp):
// configs, whole runs (run_bd / restart_bd, what `rpyfmm bd` calls) and a
// steppable Simulation around bd::Integrator with Python force callbacks.
//
//   dx = M F dt + sqrt(2 kT dt) M^{1/2} z   (Euler-Maruyama, integrator.hpp)
//
// Units are the caller's: lengths, time dt, energy kT, viscosity eta with
// mobility 1/(6 pi eta a); forces in energy/length.
#include <nanobind/stl/filesystem.h>
#include <nanobind/stl/map.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/string_view.h>

#include <algorithm>
#include <filesystem>
#include <ios>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <system_error>

#include "common.hpp"
#include "device_arrays.hpp"
#include "object_lock.hpp"
#include "rpyfmm/bd/config.hpp"
#include "rpyfmm/bd/integrator.hpp"
#include "rpyfmm/bd/particles.hpp"
#include "rpyfmm/bd/run.hpp"
#include "rpyfmm/bd/step_engine.hpp"
#include "rpyfmm/core/ranges.hpp"
#include "rpyfmm/rpy/mobility_factory.hpp"
#include "run_arguments.hpp"

namespace rpyfmm::python {
namespace {

/// The Python force callable of a Simulation; owned by it, outlives the integrator.
struct PyForce {
  nb::object callable;
};

/// Adds the callable's forces: f(positions (N, 3) read-only, step, forces (N, 3) writable) may add
/// into `forces` in place and/or return an array to add. Both arrays own their memory (copies of
/// the integrator's buffers, about 1 ms each at N = 1e5), so a callable that keeps them never reads
/// or writes freed memory; what it writes into `forces` after returning has no effect.
bd::ForceCallback make_callback(PyForce* state) {
  return [state](std::span<const double> x, std::uint64_t step, std::span<double> f) {
    nb::gil_scoped_acquire acquire;
    const std::vector<std::size_t> shape{x.size() / 3, 3};
    const ArrayResult xv = read_only_copy(x, shape);
    const OutArray fv = make_output(nb::none(), shape, "force callback");
    std::copy(f.begin(), f.end(), fv.data);
    nb::object r = state->callable(xv.o, step, fv.object);
    std::copy(fv.data, fv.data + fv.size, f.begin());
    if (r.is_none()) return;
    const InArray add = as_input(r, "force callback", "returned forces");
    require(
        add.size == f.size(), ErrorCode::invalid_input, "force callback",
        "returned forces has shape " + shape_string(add.shape) + ", expected (" + std::to_string(shape[0]) + ", 3)");
    for (std::size_t i = 0; i < f.size(); ++i) f[i] += add.data[i];
  };
}

}  // namespace

bd::PairPotential pair_from(nb::handle pair, const std::string& where) {
  bd::PairPotential p;
  std::string kind;
  if (nb::try_cast(pair, kind, false)) {
    p.kind = bd::pair_kind_from_string(kind);
    return p;
  }
  if (!nb::isinstance<nb::dict>(pair)) {
    fail(ErrorCode::invalid_argument, where, "pair must be None, a kind name or a dict of PairPotential fields");
  }
  for (auto [key, value] : nb::borrow<nb::dict>(pair)) {
    const std::string k = nb::cast<std::string>(key);
    if (k == "kind")
      p.kind = bd::pair_kind_from_string(nb::cast<std::string>(value));
    else if (k == "epsilon")
      p.epsilon = nb::cast<double>(value);
    else if (k == "sigma")
      p.sigma = nb::cast<double>(value);
    else if (k == "cutoff")
      p.cutoff = nb::cast<double>(value);
    else if (k == "min_distance_fraction")
      p.min_distance_fraction = nb::cast<double>(value);
    else
      fail(ErrorCode::invalid_argument, where,
           "unknown pair key '" + k + "' (expected kind, epsilon, sigma, cutoff, min_distance_fraction)");
  }
  return p;
}

namespace {

/// Per-particle radii of a Simulation: one number for all, or (N,) radii.
std::vector<double> simulation_radii(RadiusArg radius, std::size_t n, const std::string& where) {
  if (nb::hasattr(radius, "ndim") ? nb::cast<int>(radius.h.attr("ndim")) > 0
                                  : (nb::isinstance<nb::list>(radius.h) || nb::isinstance<nb::tuple>(radius.h))) {
    const InArray r = as_input(radius, where, "radii");
    require(r.ndim() == 1 && r.size == n, ErrorCode::invalid_input, where,
            "radii has shape " + shape_string(r.shape) + ", expected (" + std::to_string(n) + ",)");
    return {r.data, r.data + r.size};
  }
  return std::vector<double>(n, nb::cast<double>(radius.h));
}

/// Particle types from radii, one type per distinct radius: the types (sorted by radius) and each
/// particle's type.
std::pair<std::vector<bd::ParticleType>, std::vector<std::uint32_t>> types_of(const std::vector<double>& radii) {
  std::vector<double> distinct = radii;
  std::sort(distinct.begin(), distinct.end());
  distinct.erase(std::unique(distinct.begin(), distinct.end()), distinct.end());
  std::vector<bd::ParticleType> types;
  for (std::size_t t = 0; t < distinct.size(); ++t) {
    bd::ParticleType type;
    type.name = "t" + std::to_string(t);
    type.radius = distinct[t];
    types.push_back(type);
  }
  std::vector<std::uint32_t> type_of(radii.size());
  for (std::size_t i = 0; i < radii.size(); ++i) {
    type_of[i] =
        static_cast<std::uint32_t>(std::lower_bound(distinct.begin(), distinct.end(), radii[i]) - distinct.begin());
  }
  return {std::move(types), std::move(type_of)};
}

/// The pair potential (None: none) between every two types and the external force (None: none).
bd::ForceField simulation_forces(std::vector<bd::ParticleType> types, nb::handle pair, OptArrayArg external_force,
                                 const std::string& where) {
  const std::size_t count = types.size();
  bd::ForceField forces(std::move(types));
  if (!pair.is_none()) {
    const bd::PairPotential p = pair_from(pair, where);
    for (std::uint32_t a = 0; a < count; ++a)
      for (std::uint32_t b = a; b < count; ++b) forces.set_pair(a, b, p);
  }
  if (!external_force.is_none()) {
    const InArray g = as_input(external_force, where, "external_force");
    require(g.size == 3, ErrorCode::invalid_input, where,
            "external_force has shape " + shape_string(g.shape) + ", expected (3,)");
    forces.set_global_force({g.data[0], g.data[1], g.data[2]});
  }
  return forces;
}

/// The Brownian square root of a Simulation: method, tolerance and preconditioner.
rpy::SqrtOptions simulation_sqrt(const std::string& method, double tolerance, const std::string& preconditioner,
                                 const std::string& where) {
  // Checked for every mobility: PSE's split sampler ignores the tolerance and would take NaN.
  ranges::require_in(ranges::kSolverTolerance, tolerance, where, "sqrt_tolerance");
  rpy::SqrtOptions o = bd::IntegratorOptions{}.sqrt;
  o.method = sqrt_method_from(method);
  o.tolerance = tolerance;
  o.preconditioner = sqrt_preconditioner_from(preconditioner);
  if (o.preconditioner == rpy::SqrtPreconditioner::block && o.method != rpy::SqrtMethod::lanczos &&
      o.method != rpy::SqrtMethod::chebyshev && o.method != rpy::SqrtMethod::automatic)
    fail(ErrorCode::invalid_argument, where,
         "sqrt_preconditioner 'block' needs sqrt_method 'lanczos', 'chebyshev' or 'auto'");
  return o;
}

/// "cuda" | "host": what runs the device engine's stages (bd::DeviceLauncher).
bd::DeviceLauncher launcher_from(const std::string& name) {
  if (name == "cuda") return bd::DeviceLauncher::cuda;
  if (name == "host") return bd::DeviceLauncher::host;
  fail(ErrorCode::invalid_argument, "Simulation", "unknown device_launcher '" + name + "' (expected cuda or host)");
}

/// The engine `spec` asks for (device 'cuda' with mobility 'none', or 'pse' in a periodic box: the
/// device engine, run by `launcher`; docs/gpu-bd.md). A Python force is refused there: the device
/// step has no host round trip to call it.
bd::StepEngine simulation_engine(const rpy::MobilitySpec& spec, const std::string& launcher, nb::handle force) {
  const bd::StepEngine engine = bd::step_engine_for(spec, launcher_from(launcher));
  require(force.is_none() || engine == bd::StepEngine::cpu, ErrorCode::not_supported, "Simulation",
          "a Python force callback (force=...) cannot run on the device engine (device 'cuda' with mobility "
          "'none' or 'pse' runs the whole step on the GPU, without a host round trip); give the forces as pair "
          "potentials, bonds or external forces (pair=, external_force=; a config's [[pair]], [bonds], "
          "[external]), or use device='cpu'");
  return engine;
}

class Simulation {
 public:
  /// From arrays and keywords (see the binding's docstring); `sqrt_tol` is the deprecated spelling of
  /// `sqrt_tolerance`.
  Simulation(ArrayArg positions, RadiusArg radius, double dt, double kT, std::uint64_t seed,
             const std::string& mobility, double viscosity, BoxArg box, double tolerance,
             const std::string& sqrt_method, std::optional<double> sqrt_tolerance, double max_displacement,
             OptArrayArg external_force, nb::handle force, nb::handle pair, std::uint64_t first_step,
             std::size_t fmm_crossover, const std::string& sqrt_preconditioner, std::optional<double> sqrt_tol,
             const std::string& device, const std::string& device_launcher) {
    const std::string where = "Simulation";
    const InArray x = as_input(positions, where, "positions");
    const std::size_t n = require_points(x, where, "positions");
    auto [types, type_of] = types_of(simulation_radii(radius, n, where));

    rpy::MobilitySpec spec;
    spec.method = rpy::mobility_method_from_string(mobility);
    spec.tolerance = tolerance;
    spec.viscosity = viscosity;
    spec.geometry = geometry_from(box, where);
    spec.fmm_crossover = fmm_crossover;
    spec.device = rpy::compute_device_from_string(device, "Simulation");
    bd::IntegratorOptions o;
    o.engine = simulation_engine(spec, device_launcher, force);
    bd::ForceField forces = simulation_forces(std::move(types), pair, external_force, where);
    add_force(forces, force);
    o.dt = dt;
    o.kT = kT;
    o.seed = seed;
    const double sqrt_t = renamed_keyword(sqrt_tolerance, sqrt_tol, 1e-3, where, "sqrt_tolerance", "sqrt_tol");
    o.sqrt = simulation_sqrt(sqrt_method, sqrt_t, sqrt_preconditioner, where);
    o.max_displacement = max_displacement;
    bd::NeighbourOptions neighbours;
    integrator_ = std::make_unique<bd::Integrator>(bd::engine_mobility(spec, o.engine, n), std::move(forces), o,
                                                   std::vector<double>(x.data, x.data + x.size), std::move(type_of),
                                                   neighbours, first_step);
  }

  /// From a run config: the same particles, forces, mobility and engine as `rpyfmm bd` (run.cpp).
  Simulation(const bd::RunConfig& config, nb::handle force, const std::string& device_launcher) {
    bd::IntegratorOptions o = config.integrator;
    o.engine = simulation_engine(config.mobility, device_launcher, force);
    bd::ForceField forces = bd::make_force_field(config);
    const bd::InitialState start = bd::make_particles(config, forces);
    forces.add_bonds(start.bonds);
    add_force(forces, force);
    const std::size_t n = start.types.size();
    integrator_ =
        std::make_unique<bd::Integrator>(bd::engine_mobility(config.mobility, o.engine, n), std::move(forces), o,
                                         start.positions, start.types, config.neighbours, 0, start.orientations);
  }

  /// The Python force (None when there is none) for the cyclic garbage collector.
  [[nodiscard]] nb::handle python_force() const { return py_force_ ? py_force_->callable : nb::handle(); }
  /// Drops the Python force (tp_clear: breaking a reference cycle; a later step raises TypeError).
  void clear_python_force() {
    if (py_force_) py_force_->callable = nb::none();
  }

  bd::Integrator& integrator() { return *integrator_; }
  /// After steps on the device engine: its positions and forces copied to the host arrays that
  /// the live views show (a no-op on the CPU engine, whose arrays they are).
  void refresh_views() const {
    (void)integrator_->positions();
    (void)integrator_->last_forces();
  }
  [[nodiscard]] const bd::Integrator& integrator() const { return *integrator_; }

 private:
  void add_force(bd::ForceField& forces, nb::handle force) {
    if (force.is_none()) return;
    require(PyCallable_Check(force.ptr()) != 0, ErrorCode::invalid_argument, "Simulation",
            "force must be a callable f(positions, step, forces) or None");
    py_force_ = std::make_unique<PyForce>(PyForce{nb::borrow(force)});
    forces.add_callback(make_callback(py_force_.get()));
  }

  std::unique_ptr<PyForce> py_force_;  // declared first: destroyed after the integrator
  std::unique_ptr<bd::Integrator> integrator_;
};

/// A read-only (values.size() / columns, columns) view of values, kept alive by `owner`.
ArrayResult view_of(std::span<const double> values, nb::handle owner, std::size_t columns = 3) {
  const std::size_t shape[2] = {values.size() / columns, columns};
  return {nb::cast(nb::ndarray<nb::numpy, const double>(values.data(), 2, shape, owner), nb::rv_policy::reference)};
}

// A force callable often refers back to its Simulation (a closure, or module globals), a
// reference cycle: the type takes part in cyclic garbage collection (nanobind docs,
// "Reference cycles involving functions and classes").
int simulation_traverse(PyObject* self, visitproc visit, void* arg) {
  Py_VISIT(Py_TYPE(self));
  if (!nb::inst_ready(self)) return 0;
  Py_VISIT(nb::inst_ptr<Simulation>(self)->python_force().ptr());
  return 0;
}

int simulation_clear(PyObject* self) {
  if (nb::inst_ready(self)) nb::inst_ptr<Simulation>(self)->clear_python_force();
  return 0;
}

PyType_Slot simulation_slots[] = {{Py_tp_traverse, reinterpret_cast<void*>(simulation_traverse)},
                                  {Py_tp_clear, reinterpret_cast<void*>(simulation_clear)},
                                  {0, nullptr}};

using SimulationClass = nb::class_<Simulation>;

/// Simulation's steps.
void add_simulation_steps(SimulationClass& cls) {
  cls.def("step",
          locked(
              "Simulation.step",
              +[](Simulation& s) {
                bd::StepReport r;
                {
                  nb::gil_scoped_release release;
                  r = s.integrator().step();
                  s.refresh_views();
                }
                return r;
              }),
          "Advances one step; on a blow-up or a force error the state stays at the last good step and an\n"
          "exception is raised (the Python force's own exception unchanged).")
      .def("run",
           locked(
               "Simulation.run",
               +[](Simulation& s, std::uint64_t count) {
                 nb::gil_scoped_release release;
                 s.integrator().run(count);
                 s.refresh_views();
               }),
           nb::arg("count"), "Advances `count` steps.");
}

/// Simulation's state: positions, forces, counters.
void add_simulation_state(SimulationClass& cls) {
  cls.def_prop_ro(
         "positions",
         [](nb::handle self) { return view_of(nb::cast<Simulation&>(self).integrator().positions(), self); },
         "Live read-only view (N, 3) of the unwrapped positions (updated in place by step; copy to keep).")
      .def_prop_ro(
          "last_forces",
          [](nb::handle self) { return view_of(nb::cast<Simulation&>(self).integrator().last_forces(), self); },
          "Live read-only view (N, 3) of the forces at the start of the last step.")
      .def_prop_ro(
          "orientations",
          [](nb::handle self) { return view_of(nb::cast<Simulation&>(self).integrator().orientations(), self, 4); },
          "Live read-only view (N, 4) of the orientations, unit quaternions (w, x, y, z), of a config with\n"
          "[system] rotation = true (docs/bd-config.md, Rotation); shape (0, 4) without rotation.")
      .def_prop_ro("radii",
                   locked_read(
                       "Simulation.radii",
                       +[](const Simulation& s) {
                         auto r = s.integrator().radii();
                         return adopt_vector(std::vector<double>(r.begin(), r.end()), {r.size()});
                       }),
                   "Copy of the radii (N,).")
      .def_prop_ro(
          "size", [](const Simulation& s) { return s.integrator().size(); }, "Number of particles N.")
      .def(
          "__len__", [](const Simulation& s) { return s.integrator().size(); }, "N, as size.")
      .def_prop_ro("step_count",
                   locked_read(
                       "Simulation.step_count", +[](const Simulation& s) { return s.integrator().step_count(); }),
                   "Number of the current step (first_step + steps taken).")
      .def_prop_ro("time",
                   locked_read(
                       "Simulation.time", +[](const Simulation& s) { return s.integrator().time(); }),
                   "step_count * dt.")
      .def_prop_ro(
          "dt", [](const Simulation& s) { return s.integrator().options().dt; }, "Time step (time units).")
      .def_prop_ro(
          "kT", [](const Simulation& s) { return s.integrator().options().kT; }, "Thermal energy (energy units).")
      .def_prop_ro(
          "mobility", [](const Simulation& s) { return s.integrator().mobility().name(); },
          "Name of the mobility operator in use ('none', 'direct', 'fmm', 'pse').")
      .def_prop_ro(
          "engine", [](const Simulation& s) { return std::string(bd::to_string(s.integrator().options().engine)); },
          "What runs the steps: 'cpu', 'cuda' (the device engine, docs/gpu-bd.md) or 'host launcher' (the\n"
          "device engine's stages on the CPU, device_launcher='host').")
      .def_prop_ro("neighbour_rebuilds",
                   locked_read(
                       "Simulation.neighbour_rebuilds",
                       +[](const Simulation& s) { return s.integrator().neighbour_rebuilds(); }),
                   "Neighbour-list rebuilds so far.")
      .def_prop_ro("last_report",
                   locked_read(
                       "Simulation.last_report", +[](const Simulation& s) { return s.integrator().last_report(); }),
                   "The StepReport of the last step.")
      .def("totals",
           locked_read(
               "Simulation.totals",
               +[](const Simulation& s) {
                 const bd::IntegratorTotals& t = s.integrator().totals();
                 nb::dict d;
                 d["steps"] = t.steps;
                 d["sqrt_iterations"] = t.sqrt_iterations;
                 d["mobility_products"] = t.mobility_products;
                 d["seconds"] = t.seconds;
                 return d;
               }),
           "Cumulative counters and seconds per part.");
}

/// A view of the device engine's positions or forces in place (docs/python.md, "Device arrays").
nb::object engine_view(const Simulation& s, const char* where, bool forces) {
  const std::optional<bd::Stepper::StateView> state = s.integrator().engine_state();
  require(state.has_value(), ErrorCode::not_supported, where,
          std::string("the '") + bd::to_string(s.integrator().options().engine) +
              "' engine keeps its state in its own host arrays: read Simulation.positions and last_forces; "
              "device views are offered by the device engine (device='cuda', docs/gpu-bd.md)");
  return read_only_view(forces ? state->forces : state->positions, state->size, state->device, nb::find(s));
}

/// Views of the device engine's state, no copy: its positions and forces in device memory.
void add_simulation_device_views(SimulationClass& cls) {
  cls.def("device_positions",
          locked_read(
              "Simulation.device_positions",
              +[](const Simulation& s) { return engine_view(s, "Simulation.device_positions", false); }),
          "The device engine's positions (N, 3) in place, with no copy: a DLPack array flagged read-only\n"
          "(DLPack 1.0; not to be written) on the GPU (kDLCUDA; cupy.from_dlpack, torch.from_dlpack) or,\n"
          "with device_launcher='host', in host memory (kDLCPU; numpy.from_dlpack). Particle order as given\n"
          "(the engine does not reorder them). Valid until the next step, which writes the positions into\n"
          "the engine's other buffer: take a new view after each step. It keeps the Simulation alive.\n"
          "NotSupportedError on the CPU engine.")
      .def("device_forces",
           locked_read(
               "Simulation.device_forces",
               +[](const Simulation& s) { return engine_view(s, "Simulation.device_forces", true); }),
           "The device engine's forces (N, 3) at the start of the last step, in place as device_positions\n"
           "(each step rewrites them).");
}

void bind_run_config(nb::module_& m) {
  nb::class_<bd::RunConfig>(m, "RunConfig", "A parsed BD run configuration (docs/bd-config.md).")
      .def_prop_rw(
          "steps", [](const bd::RunConfig& c) { return c.steps; },
          [](bd::RunConfig& c, std::uint64_t s) { c.steps = s; }, "Total number of steps.")
      .def_prop_rw(
          "dt", [](const bd::RunConfig& c) { return c.integrator.dt; },
          [](bd::RunConfig& c, double v) { c.integrator.dt = v; }, "Time step (time units).")
      .def_prop_rw(
          "kT", [](const bd::RunConfig& c) { return c.integrator.kT; },
          [](bd::RunConfig& c, double v) { c.integrator.kT = v; }, "Thermal energy (energy units).")
      .def_prop_rw(
          "seed", [](const bd::RunConfig& c) { return c.integrator.seed; },
          [](bd::RunConfig& c, std::uint64_t v) { c.integrator.seed = v; }, "Noise seed.")
      .def_prop_rw(
          "out_dir", [](const bd::RunConfig& c) { return c.output.dir.string(); },
          [](bd::RunConfig& c, const std::string& v) { c.output.dir = v; }, "Output directory.")
      .def_prop_ro(
          "viscosity", [](const bd::RunConfig& c) { return c.viscosity; }, "Solvent viscosity eta.")
      .def_prop_ro(
          "box", [](const bd::RunConfig& c) { return box_tuple(c.geometry); },
          "(Lx, Ly, Lz) of the periodic box, or None in free space.")
      .def_prop_ro(
          "mobility", [](const bd::RunConfig& c) { return std::string(rpy::to_string(c.mobility.method)); },
          "Mobility method ('none', 'direct', 'fmm', 'pse', 'auto').")
      .def_prop_ro(
          "text", [](const bd::RunConfig& c) { return c.text; }, "The TOML source.")
      .def_prop_ro(
          "source", [](const bd::RunConfig& c) { return c.source; },
          "Where the TOML came from (a path or '<python string>'), as error messages name it.");
  m.def(
      "load_config",
      [](const std::filesystem::path& p) { return reading_file("load_config", p, [&] { return bd::load_config(p); }); },
      nb::arg("path"), "Reads and parses a TOML run config (strict: unknown or bad keys raise, naming the key).");
  m.def("parse_config", &bd::parse_config, nb::arg("text"), nb::arg("source") = "<python string>",
        "Parses TOML text; `source` names it in error messages.");
  m.def(
      "demo_config_text", [] { return std::string(bd::demo_config_text()); },
      "TOML of the built-in demo (2000 sedimenting spheres with HI).");
}

/// Whole runs, as `rpyfmm bd`.
void bind_runs(nb::module_& m) {
  m.def(
      "run_bd",
      [](nb::handle config, std::optional<std::uint64_t> steps, std::optional<std::string> out_dir, bool progress) {
        const bd::RunConfig c = config_from(config);
        const bd::RunOptions o = run_options(steps, out_dir, progress);
        bd::RunSummary s;
        {
          nb::gil_scoped_release release;
          s = bd::run_bd(c, o);
        }
        return summary_dict(s);
      },
      nb::arg("config"), nb::arg("steps") = nb::none(), nb::arg("out_dir") = nb::none(), nb::arg("progress") = false,
      "Runs a whole BD config as `rpyfmm bd` does (trajectory, log, checkpoint in out_dir).\n"
      "config: RunConfig, path to a TOML file, or TOML text. Returns the run summary as a dict.");
  m.def(
      "restart_bd",
      [](const std::filesystem::path& checkpoint, std::optional<std::uint64_t> steps,
         std::optional<std::string> out_dir, bool progress) {
        const bd::RunOptions o = run_options(steps, out_dir, progress);
        bd::RunSummary s;
        {
          nb::gil_scoped_release release;
          s = reading_file("restart_bd", checkpoint, [&] { return bd::restart_bd(checkpoint, o); });
        }
        return summary_dict(s);
      },
      nb::arg("checkpoint"), nb::arg("steps") = nb::none(), nb::arg("out_dir") = nb::none(),
      nb::arg("progress") = false, "Continues a run from its checkpoint, bitwise as if uninterrupted.");
}

void bind_step_report(nb::module_& m) {
  nb::class_<bd::StepReport>(m, "StepReport", "What one BD step did.")
      .def_ro("sqrt_iterations", &bd::StepReport::sqrt_iterations, "Iterations of the Brownian square root.")
      .def_ro("preconditioner_blocks", &bd::StepReport::preconditioner_blocks,
              "Blocks of the square root's block preconditioner (0: none).")
      .def_ro("mobility_products", &bd::StepReport::mobility_products, "Mobility products M x of this step.")
      .def_ro("shared_first_product", &bd::StepReport::shared_first_product,
              "True when M F and the square root's first product M z came from one block pass.")
      .def_ro("neighbour_rebuild", &bd::StepReport::neighbour_rebuild, "True when the neighbour list was rebuilt.")
      .def_ro("potential_energy", &bd::StepReport::potential_energy, "Total potential energy (energy units).");
}

void bind_simulation(nb::module_& m) {
  SimulationClass cls(m, "Simulation", nb::type_slots(simulation_slots),
                      "Steppable Brownian dynamics with hydrodynamic interactions (bd::Integrator):\n"
                      "  dx = M F dt + sqrt(2 kT dt) M^{1/2} z.\n"
                      "The GIL is released while stepping and taken only to call the Python force.");
  cls.def(
         nb::init<ArrayArg, RadiusArg, double, double, std::uint64_t, const std::string&, double, BoxArg, double,
                  const std::string&, std::optional<double>, double, OptArrayArg, nb::handle, nb::handle, std::uint64_t,
                  std::size_t, const std::string&, std::optional<double>, const std::string&, const std::string&>(),
         nb::arg("positions"), nb::arg("radius") = 1.0, nb::kw_only(), nb::arg("dt"), nb::arg("kT") = 1.0,
         nb::arg("seed") = 1, nb::arg("mobility") = "auto", nb::arg("viscosity") = 1.0, nb::arg("box") = nb::none(),
         nb::arg("tolerance") = 1e-3, nb::arg("sqrt_method") = "auto",
         nb::arg("sqrt_tolerance").sig("0.001") = nb::none(), nb::arg("max_displacement") = 1.0,
         nb::arg("external_force") = nb::none(), nb::arg("force") = nb::none(), nb::arg("pair") = nb::none(),
         nb::arg("first_step") = 0, nb::arg("fmm_crossover") = 0, nb::arg("sqrt_preconditioner") = "auto",
         nb::arg("sqrt_tol") = nb::none(), nb::arg("device") = "cpu", nb::arg("device_launcher") = "cuda",
         "positions: (N, 3) (length units, copied); radius: a number or (N,) radii; dt: time step; kT: thermal\n"
         "energy; mobility: 'none', 'direct', 'fmm', 'pse', 'auto'; box: None, L or (Lx, Ly, Lz);\n"
         "tolerance: of the fmm/pse product; sqrt_method/sqrt_tolerance: Brownian square root (sqrt_tol:\n"
         "the deprecated spelling of sqrt_tolerance);\n"
         "sqrt_preconditioner: 'auto' (block-preconditioned Krylov, direct/fmm), 'block' or 'none';\n"
         "max_displacement: blow-up guard in radii per step; external_force: (3,) force on every particle;\n"
         "force: callable f(positions, step, forces) adding into forces (N, 3) in place and/or returning an\n"
         "array to add (energy/length; both arrays are copies it may keep);\n"
         "pair: None, 'wca', 'lj36_18', 'soft' or a dict of PairPotential fields;\n"
         "fmm_crossover: particles from which 'auto' uses fmm (0 = default_fmm_crossover(tolerance));\n"
         "device: 'cpu', or 'cuda': with mobility 'none', or 'pse' in a periodic box, the device engine runs\n"
         "the whole step on the GPU (docs/gpu-bd.md; no force callable there);\n"
         "device_launcher: what runs the device engine, 'cuda', or 'host': its stages on the CPU with the same\n"
         "results bit for bit (for machines without a GPU).")
      .def_static(
          "from_config",
          [](nb::handle config, nb::handle force, const std::string& device_launcher) {
            return new Simulation(config_from(config), force, device_launcher);
          },
          nb::arg("config"), nb::arg("force") = nb::none(), nb::kw_only(), nb::arg("device_launcher") = "cuda",
          nb::rv_policy::take_ownership,
          "The particles, forces, mobility and engine of a BD config (RunConfig, path or TOML text), plus an\n"
          "optional Python force; stepping it reproduces `run_bd` bitwise when force is None. [mobility]\n"
          "device = \"cuda\" with method = \"none\" runs the device engine (no force callable there),\n"
          "device_launcher='host' its stages on the CPU.");
  add_simulation_steps(cls);
  add_simulation_state(cls);
  add_simulation_device_views(cls);
}

}  // namespace

void bind_bd(nb::module_& m) {
  bind_run_config(m);
  bind_runs(m);
  bind_step_report(m);
  bind_simulation(m);
}

}  // namespace rpyfmm::python
