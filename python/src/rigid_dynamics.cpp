// rpyfmm Python bindings — Brownian dynamics of rigid bodies of beads
// (bd/include/rpyfmm/bd/rigid_dynamics.hpp): RigidBodyDynamics with a Python force function, its
// step report, and the quaternion helpers.
#include "rpyfmm/bd/rigid_dynamics.hpp"

#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <memory>
#include <optional>

#include "common.hpp"
#include "object_lock.hpp"

namespace rpyfmm::python {
namespace {

using bd::RigidBodyDynamics;
using bd::RigidStepReport;

/// The Python object, holding the simulation, the force callable it calls and the bead operator
/// it drives (kept alive by the Python object; its lock is taken with this object's).
struct PyRigidBodyDynamics {
  nb::object forces;  ///< None or forces(time, positions (m,3), orientations (m,4), beads (N,3)) -> (m,6)
  std::unique_ptr<RigidBodyDynamics> sim;
  rpy::MobilityOperator* beads = nullptr;
};

LockPtr inner_lock_of(const PyRigidBodyDynamics& self) {
  return self.beads ? lock_of(*self.beads) : nullptr;
}

std::vector<double> to_vector(ArrayArg a, const std::string& where, const std::string& name) {
  const InArray in = as_input(a, where, name);
  return {in.data, in.data + in.size};
}

/// (m, 4) quaternions, or none (identity orientations).
std::vector<double> orientations_from(OptArrayArg orientations, const std::string& where) {
  if (orientations.is_none()) return {};
  const InArray o = as_input(orientations, where, "orientations");
  require(o.ndim() == 2 && o.shape[1] == 4, ErrorCode::invalid_input, where,
          "orientations has shape " + shape_string(o.shape) + ", expected (m, 4) quaternions (w, x, y, z)");
  return {o.data, o.data + o.size};
}

bd::RigidDrift drift_from(const std::string& drift, const std::string& where) {
  if (drift == "rfd" || drift == "random_finite_difference") return bd::RigidDrift::random_finite_difference;
  if (drift == "none") return bd::RigidDrift::none;
  fail(ErrorCode::invalid_argument, where, "drift must be 'rfd' or 'none', got '" + drift + "'");
}

/// The body forces of `self->forces` (None: no function). `self` is the object's storage, constructed
/// after this; the function runs only after that.
bd::BodyForceFunction body_forces(PyRigidBodyDynamics* self, const nb::object& forces, const std::string& where) {
  require(forces.is_none() || PyCallable_Check(forces.ptr()), ErrorCode::invalid_argument, where,
          "forces must be None or a callable forces(time, positions, orientations, bead_positions) -> (m, 6)");
  if (forces.is_none()) return {};
  return [self](const bd::RigidBodyState& state, std::span<double> w) {
    // Called from step(), which runs without the GIL; the arrays are copies the callable may keep.
    nb::gil_scoped_acquire acquire;
    const std::string name = "RigidBodyDynamics forces";
    nb::object result = self->forces(state.time, copy_rows(state.positions, 3).o, copy_rows(state.orientations, 4).o,
                                     copy_rows(state.bead_positions, 3).o);
    const InArray f = as_input(ArrayArg{result}, name, "the forces function's result");
    require(f.size == w.size(), ErrorCode::invalid_input, name,
            "the forces function returned shape " + shape_string(f.shape) + ", expected (m, 6) = (" +
                std::to_string(w.size() / 6) + ", 6)");
    std::copy(f.data, f.data + f.size, w.begin());
  };
}

/// RigidBodyDynamics(...); `sqrt_tol` is the deprecated spelling of `sqrt_tolerance`.
void init(PyRigidBodyDynamics* self, rpy::MobilityOperator& beads, ArrayArg shape, RadiusArg radius,
          const std::vector<std::size_t>& body_offsets, ArrayArg positions, OptArrayArg orientations, double dt,
          double kT, std::uint64_t seed, std::uint64_t first_step, const std::string& drift, double rfd_delta,
          double tolerance, int max_iterations, std::optional<double> sqrt_tolerance, const std::string& preconditioner,
          double max_displacement, nb::object forces, nb::handle pair, std::optional<double> sqrt_tol) {
  const std::string where = "RigidBodyDynamics";
  const CallGuard hold = guard(where, beads);
  const InArray rho = as_input(shape, where, "shape");
  require_points(rho, where, "shape");
  // One radius or N (RigidBodyDynamics takes a 1-element vector as one radius for all beads).
  std::vector<double> radii = radii_from(radius, where).values;
  const InArray q = as_input(positions, where, "positions");
  require_points(q, where, "positions");
  const double sqrt_t = renamed_keyword(sqrt_tolerance, sqrt_tol, 1e-3, where, "sqrt_tolerance", "sqrt_tol");
  const bd::RigidDynamicsOptions options{
      .dt = dt,
      .kT = kT,
      .seed = seed,
      .first_step = first_step,
      .drift = drift_from(drift, where),
      .rfd_delta = rfd_delta,
      .solver = {.tolerance = tolerance, .max_iterations = max_iterations},
      .sqrt = sqrt_options("auto", sqrt_t, 0, true, true, 0.0, 0.0, 30, preconditioner, 0),
      .max_displacement = max_displacement};
  bd::BodyForceFunction function = body_forces(self, forces, where);
  auto simulation =
      std::make_unique<RigidBodyDynamics>(beads, std::vector<double>(rho.data, rho.data + rho.size), std::move(radii),
                                          body_offsets, std::vector<double>(q.data, q.data + q.size),
                                          orientations_from(orientations, where), options, std::move(function));
  if (!pair.is_none()) {
    // One bead type with the first bead's radius: sigma = 0 means twice that (contact).
    bd::ForceField field({bd::ParticleType{.radius = simulation->radii()[0]}});
    field.set_pair(0, 0, pair_from(pair, where));
    simulation->set_bead_forces(std::move(field));
  }
  new (self) PyRigidBodyDynamics{forces, std::move(simulation), &beads};
}

/// Steps without the GIL (the force function takes it while it runs).
RigidStepReport run(PyRigidBodyDynamics& self, std::uint64_t steps) {
  nb::gil_scoped_release release;
  self.sim->run(steps);
  return self.sim->last_report();
}

RigidBodyDynamics& sim(PyRigidBodyDynamics& self) {
  require(self.sim != nullptr, ErrorCode::invalid_input, "RigidBodyDynamics", "not initialized");
  return *self.sim;
}

using DynamicsClass = nb::class_<PyRigidBodyDynamics>;

/// RigidBodyDynamics's steps and body-force helpers.
void add_dynamics_methods(DynamicsClass& cls) {
  cls.def("step",
          locked(
              "RigidBodyDynamics.step", +[](PyRigidBodyDynamics& self) { return run(self, 1); }),
          "One step; returns its RigidStepReport.")
      .def("run", locked("RigidBodyDynamics.run", &run), nb::arg("steps"),
           "Advances `steps` steps; returns the last step's RigidStepReport.")
      .def("drift_estimate",
           locked(
               "RigidBodyDynamics.drift_estimate",
               +[](PyRigidBodyDynamics& self, ArrayArg w) {
                 const std::string where = "RigidBodyDynamics.drift_estimate";
                 const std::vector<double> direction = to_vector(w, where, "w");
                 std::vector<double> out(6 * sim(self).bodies());
                 {
                   nb::gil_scoped_release release;  // two GMRES solves
                   sim(self).drift_estimate(direction, out);
                 }
                 return adopt_vector(std::move(out), {sim(self).bodies(), 6});
               }),
           nb::arg("w"),
           "(1/delta)[N(Q + delta/2 S w) - N(Q - delta/2 S w)] S^{-1} w (m, 6) for w (6m): its mean over\n"
           "standard normal w (and its sum over unit vectors) is the divergence d/dQ . N.")
      .def("bead_forces_to_bodies",
           locked(
               "RigidBodyDynamics.bead_forces_to_bodies",
               +[](PyRigidBodyDynamics& self, ArrayArg f) {
                 const std::vector<double> forces =
                     to_vector(f, "RigidBodyDynamics.bead_forces_to_bodies", "bead_forces");
                 std::vector<double> w(6 * sim(self).bodies(), 0.0);
                 sim(self).bead_forces_to_bodies(forces, w);
                 return adopt_vector(std::move(w), {sim(self).bodies(), 6});
               }),
           nb::arg("bead_forces"), "Forces and torques (m, 6) of bead forces (N, 3) at the current bead positions.");
}

/// RigidBodyDynamics's state: bodies, beads, last step, counters.
void add_dynamics_state(DynamicsClass& cls) {
  cls.def_prop_ro(
         "positions",
         locked_read(
             "RigidBodyDynamics.positions", +[](PyRigidBodyDynamics& s) { return copy_rows(sim(s).positions(), 3); }),
         "Reference points (m, 3), unwrapped.")
      .def_prop_ro("orientations",
                   locked_read(
                       "RigidBodyDynamics.orientations",
                       +[](PyRigidBodyDynamics& s) { return copy_rows(sim(s).orientations(), 4); }),
                   "Unit quaternions (m, 4) (w, x, y, z).")
      .def_prop_ro("bead_positions",
                   locked_read(
                       "RigidBodyDynamics.bead_positions",
                       +[](PyRigidBodyDynamics& s) { return copy_rows(sim(s).bead_positions(), 3); }),
                   "Bead positions (N, 3) = q_k + R_k rho_i, unwrapped.")
      .def_prop_ro("lever_arms",
                   locked_read(
                       "RigidBodyDynamics.lever_arms",
                       +[](PyRigidBodyDynamics& s) {
                         const auto l = sim(s).lever_arms();
                         return adopt_vector(std::vector<double>(l.begin(), l.end()), {l.size()});
                       }),
                   "Each body's RMS lever arm (m,).")
      .def_prop_ro("bodies",
                   locked_read(
                       "RigidBodyDynamics.bodies", +[](PyRigidBodyDynamics& s) { return sim(s).bodies(); }),
                   "Number of bodies m.")
      .def_prop_ro("beads",
                   locked_read(
                       "RigidBodyDynamics.beads", +[](PyRigidBodyDynamics& s) { return sim(s).beads(); }),
                   "Number of beads N.")
      .def_prop_ro("time",
                   locked_read(
                       "RigidBodyDynamics.time", +[](PyRigidBodyDynamics& s) { return sim(s).time(); }),
                   "step_count * dt (time units).")
      .def_prop_ro("step_count",
                   locked_read(
                       "RigidBodyDynamics.step_count", +[](PyRigidBodyDynamics& s) { return sim(s).step_count(); }),
                   "Step number of the current state (first_step + steps taken).");
}

/// RigidBodyDynamics's last step and counters.
void add_dynamics_last_step(DynamicsClass& cls) {
  cls.def_prop_ro("last_velocities",
                  locked_read(
                      "RigidBodyDynamics.last_velocities",
                      +[](PyRigidBodyDynamics& s) { return copy_rows(sim(s).last_velocities(), 6); }),
                  "Velocities (m, 6) of the last step, noise included, drift not.")
      .def_prop_ro("last_drift",
                   locked_read(
                       "RigidBodyDynamics.last_drift",
                       +[](PyRigidBodyDynamics& s) { return copy_rows(sim(s).last_drift(), 6); }),
                   "The drift velocity (m, 6) of the last step (zeros without drift).")
      .def_prop_ro(
          "rfd_tolerance",
          locked_read(
              "RigidBodyDynamics.rfd_tolerance", +[](PyRigidBodyDynamics& s) { return sim(s).rfd_tolerance(); }),
          "GMRES tolerance of the RFD solves: min(tolerance, 1e-3 rfd_delta).")
      .def_prop_ro("last_report",
                   locked_read(
                       "RigidBodyDynamics.last_report", +[](PyRigidBodyDynamics& s) { return sim(s).last_report(); }),
                   "The RigidStepReport of the last step.")
      .def_prop_ro("last_forces_torques",
                   locked_read(
                       "RigidBodyDynamics.last_forces_torques",
                       +[](PyRigidBodyDynamics& s) { return copy_rows(sim(s).last_forces_torques(), 6); }),
                   "Forces and torques (m, 6) of the last step (force function plus bead pair forces).")
      .def_prop_ro(
          "totals",
          locked_read(
              "RigidBodyDynamics.totals", +[](PyRigidBodyDynamics& s) { return rigid_totals_dict(sim(s).totals()); }),
          "Counters and seconds per stage ('forces', 'plan', 'sqrt', 'solve', 'drift', 'update').");
}

void bind_rigid_step_report(nb::module_& m) {
  nb::class_<RigidStepReport>(m, "RigidStepReport", "What one rigid-body Brownian dynamics step did.")
      .def_ro("solve_iterations", &RigidStepReport::solve_iterations, "GMRES iterations of the velocity solve.")
      .def_ro("drift_iterations", &RigidStepReport::drift_iterations,
              "GMRES iterations of the two random-finite-difference solves (0 without drift).")
      .def_ro("sqrt_iterations", &RigidStepReport::sqrt_iterations, "Iterations of the bead square root B z.")
      .def_ro("potential_energy", &RigidStepReport::potential_energy, "Of the bead pair potential (0 without).")
      .def_ro("neighbour_rebuild", &RigidStepReport::neighbour_rebuild,
              "True when the bead neighbour list was rebuilt (pair potential only).")
      .def("__repr__", [](const RigidStepReport& r) {
        return "RigidStepReport(solve_iterations=" + std::to_string(r.solve_iterations) +
               ", drift_iterations=" + std::to_string(r.drift_iterations) +
               ", sqrt_iterations=" + std::to_string(r.sqrt_iterations) + ")";
      });
}

void bind_rigid_body_dynamics(nb::module_& m) {
  DynamicsClass cls(
      m, "RigidBodyDynamics",
      "Brownian dynamics of rigid bodies made of beads with full hydrodynamic interactions: Euler-Maruyama\n"
      "on positions and quaternions (exponential map), the noise as a random slip on the beads, and the\n"
      "thermal drift kT d/dQ . N by a random finite difference (two extra GMRES solves per step).");
  cls.def("__init__", &init, nb::arg("beads"), nb::arg("shape"), nb::arg("radius"), nb::arg("body_offsets"),
          nb::arg("positions"), nb::arg("orientations") = nb::none(), nb::kw_only(), nb::arg("dt"), nb::arg("kT") = 1.0,
          nb::arg("seed") = 1, nb::arg("first_step") = 0, nb::arg("drift") = "rfd", nb::arg("rfd_delta") = 1e-3,
          nb::arg("tolerance") = 1e-6, nb::arg("max_iterations") = 500,
          nb::arg("sqrt_tolerance").sig("0.001") = nb::none(), nb::arg("preconditioner") = "auto",
          nb::arg("max_displacement") = 1.0, nb::arg("forces") = nb::none(), nb::arg("pair") = nb::none(),
          nb::arg("sqrt_tol") = nb::none(), nb::keep_alive<1, 2>(),
          "beads: the bead mobility operator (DirectRpy, FmmRpy, PseRpy; kept alive);\n"
          "shape: (N, 3) bead positions in the bodies' frames, relative to their reference points;\n"
          "radius: a number or (N,) radii; body_offsets: m + 1 increasing indices (first 0, last N);\n"
          "positions: (m, 3) reference points; orientations: (m, 4) quaternions (w, x, y, z) or None\n"
          "(identity); dt > 0; kT >= 0; seed: key of the noise; first_step: step number of this state (a\n"
          "restart from saved positions and orientations continues a run bit for bit); drift: 'rfd' | 'none'; "
          "rfd_delta: relative\n"
          "RFD step; tolerance, max_iterations: GMRES; sqrt_tolerance, preconditioner: the bead square root\n"
          "(sqrt_tol: its deprecated spelling);\n"
          "max_displacement: refuse a step moving beads more than this many lever arms; forces: None or\n"
          "forces(time, positions (m,3), orientations (m,4), bead_positions (N,3)) -> (m, 6) forces and\n"
          "torques about the reference points; pair: None, 'wca', 'soft', 'lj36_18' or a dict of PairPotential\n"
          "fields (kind, epsilon, sigma, cutoff, min_distance_fraction): a pair potential between beads of\n"
          "different bodies (sigma 0 = twice the first bead's radius), with a neighbour list.");
  add_dynamics_methods(cls);
  add_dynamics_state(cls);
  add_dynamics_last_step(cls);
}

}  // namespace

nb::dict rigid_totals_dict(const bd::RigidDynamicsTotals& t) {
  nb::dict d, seconds;
  d["steps"] = t.steps;
  d["solve_iterations"] = t.solve_iterations;
  d["drift_iterations"] = t.drift_iterations;
  d["sqrt_iterations"] = t.sqrt_iterations;
  for (const auto& [name, value] : t.seconds) seconds[name.c_str()] = value;
  d["seconds"] = seconds;
  return d;
}

void bind_rigid_dynamics(nb::module_& m) {
  bind_rigid_step_report(m);
  bind_rigid_body_dynamics(m);
}

}  // namespace rpyfmm::python
