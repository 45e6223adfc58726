// rpyfmm Python bindings — rigid bodies of beads (rpy/include/rpyfmm/rpy/rigid_bodies.hpp):
// the body mobility by preconditioned GMRES over any mobility operator, its report, and the
// bead-shell sphere shapes.
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <optional>

#include "common.hpp"
#include "object_lock.hpp"
#include "rpyfmm/rpy/rigid_bodies.hpp"

namespace rpyfmm::python {
namespace {

using rpy::RigidBodies;
using rpy::RigidBodyReport;

/// The Python RigidBodies: the solver and the bead operator it drives (kept alive by the Python
/// object), whose lock every call takes too.
struct BoundRigidBodies {
  BoundRigidBodies(rpy::MobilityOperator& op, const rpy::RigidBodyOptions& options) : beads(op), bodies(op, options) {}
  rpy::MobilityOperator& beads;
  RigidBodies bodies;
};

LockPtr inner_lock_of(const BoundRigidBodies& b) {
  return lock_of(b.beads);
}

std::string report_repr(const RigidBodyReport& r) {
  return "RigidBodyReport(iterations=" + std::to_string(r.iterations) + ", restarts=" + std::to_string(r.restarts) +
         ", residual=" + nb::cast<std::string>(nb::repr(nb::float_(r.residual))) +
         ", seconds_solve=" + nb::cast<std::string>(nb::repr(nb::float_(r.seconds_solve))) + ")";
}

void set_configuration(BoundRigidBodies& bound, ArrayArg positions, RadiusArg radius,
                       const std::vector<std::size_t>& body_offsets, OptArrayArg reference_points) {
  const std::string where = "RigidBodies.set_configuration";
  RigidBodies& bodies = bound.bodies;
  const InArray x = as_input(positions, where, "positions");
  require_points(x, where, "positions");
  InArray q;
  if (!reference_points.h.is_none()) {
    q = as_input(reference_points, where, "reference_points");
    require_points(q, where, "reference_points");
  }
  const Radii r = radii_from(radius, where);
  nb::gil_scoped_release release;
  if (r.scalar) {
    bodies.set_configuration(x.span(), r.values[0], body_offsets, q.span());
  } else {
    bodies.set_configuration(x.span(), r.values, body_offsets, q.span());
  }
}

/// (velocities (m, 6)[, bead forces (N, 3)], report).
nb::tuple apply(const BoundRigidBodies& bound, ArrayArg forces_torques, bool with_bead_forces) {
  const std::string where = "RigidBodies.apply";
  const RigidBodies& bodies = bound.bodies;
  const InArray w = as_input(forces_torques, where, "forces_torques");
  const std::size_t m = bodies.bodies();
  require_body_rows(w, where, "forces_torques");
  OutArray y = make_output(nb::none(), {m, 6}, where);
  std::vector<double> lambda(with_bead_forces ? 3 * bodies.beads() : 0);
  RigidBodyReport report;
  {
    nb::gil_scoped_release release;
    report = bodies.apply(w.span(), y.span(), lambda);
  }
  if (!with_bead_forces) return nb::make_tuple(y.object, report);
  const std::size_t n = bodies.beads();
  return nb::make_tuple(y.object, adopt_vector(std::move(lambda), {n, 3}).o, report);
}

/// (velocities (m, 6), bead forces (N, 3), report): GMRES started from the guesses.
nb::tuple apply_from(const BoundRigidBodies& bound, ArrayArg forces_torques, ArrayArg guess_velocities,
                     ArrayArg guess_bead_forces) {
  const std::string where = "RigidBodies.apply_from";
  const RigidBodies& bodies = bound.bodies;
  const InArray w = as_input(forces_torques, where, "forces_torques");
  require_body_rows(w, where, "forces_torques");
  const InArray gy = as_input(guess_velocities, where, "guess_velocities");
  require_body_rows(gy, where, "guess_velocities");
  const InArray gl = as_input(guess_bead_forces, where, "guess_bead_forces");
  require_points(gl, where, "guess_bead_forces");
  OutArray y = make_output(nb::none(), {bodies.bodies(), 6}, where);
  std::vector<double> lambda(3 * bodies.beads());
  RigidBodyReport report;
  {
    nb::gil_scoped_release release;
    report = bodies.apply_from(w.span(), gy.span(), gl.span(), y.span(), lambda);
  }
  return nb::make_tuple(y.object, adopt_vector(std::move(lambda), {bodies.beads(), 3}).o, report);
}

/// RigidBodies.apply_with_noise; `sqrt_tol` is the deprecated spelling of `sqrt_tolerance`.
nb::tuple apply_with_noise(const BoundRigidBodies& bound, ArrayArg forces_torques, double noise_scale, ArrayArg z,
                           std::optional<double> sqrt_tolerance, const std::string& preconditioner,
                           std::optional<double> sqrt_tol) {
  const std::string where = "RigidBodies.apply_with_noise";
  const double sqrt_t = renamed_keyword(sqrt_tolerance, sqrt_tol, 1e-3, where, "sqrt_tolerance", "sqrt_tol");
  const RigidBodies& bodies = bound.bodies;
  const InArray w = as_input(forces_torques, where, "forces_torques");
  const InArray zz = as_input(z, where, "z");
  require_points(zz, where, "z");
  require_body_rows(w, where, "forces_torques");
  const rpy::SqrtOptions options = sqrt_options("auto", sqrt_t, 0, true, true, 0.0, 0.0, 30, preconditioner, 0);
  OutArray y = make_output(nb::none(), {bodies.bodies(), 6}, where);
  RigidBodyReport report;
  {
    nb::gil_scoped_release release;
    report = bodies.apply_with_noise(w.span(), noise_scale, zz.span(), y.span(), options);
  }
  return nb::make_tuple(y.object, report);
}

using BodiesClass = nb::class_<BoundRigidBodies>;

/// RigidBodies's configuration and solves.
void add_bodies_products(BodiesClass& cls) {
  cls.def("set_configuration", locked("RigidBodies.set_configuration", &set_configuration), nb::arg("positions"),
          nb::arg("radius"), nb::arg("body_offsets"), nb::arg("reference_points") = nb::none(),
          "positions: bead positions (N, 3); radius: a number or (N,) radii; body_offsets: m + 1 increasing\n"
          "indices (body k = beads body_offsets[k] ... body_offsets[k+1] - 1; first 0, last N);\n"
          "reference_points: (m, 3) points the angular velocities and torques refer to (None: centroids).")
      .def("apply",
           locked(
               "RigidBodies.apply", +[](const BoundRigidBodies& b, ArrayArg w) { return apply(b, w, false); }),
           nb::arg("forces_torques"),
           "(velocities (m, 6), RigidBodyReport) for forces_torques (m, 6) = (F_x, F_y, F_z, T_x, T_y, T_z)\n"
           "per body; velocities = (U_x, U_y, U_z, Omega_x, Omega_y, Omega_z).")
      .def("apply_with_bead_forces",
           locked(
               "RigidBodies.apply_with_bead_forces",
               +[](const BoundRigidBodies& b, ArrayArg w) { return apply(b, w, true); }),
           nb::arg("forces_torques"),
           "(velocities (m, 6), bead forces (N, 3), RigidBodyReport): also the forces the beads exert on the\n"
           "fluid to keep the bodies rigid.")
      .def("apply_from", locked("RigidBodies.apply_from", &apply_from), nb::arg("forces_torques"),
           nb::arg("guess_velocities"), nb::arg("guess_bead_forces"),
           "(velocities (m, 6), bead forces (N, 3), RigidBodyReport) as apply_with_bead_forces, GMRES started\n"
           "from a guess instead of zero: guess_velocities (m, 6) and guess_bead_forces (N, 3) of a nearby\n"
           "problem (e.g. apply_with_bead_forces' results for nearby forces or a slightly moved\n"
           "configuration). The result meets the same tolerance, in fewer iterations the better the guess.")
      .def("apply_with_noise", locked("RigidBodies.apply_with_noise", &apply_with_noise), nb::arg("forces_torques"),
           nb::arg("noise_scale"), nb::arg("z"), nb::arg("sqrt_tolerance").sig("0.001") = nb::none(),
           nb::arg("preconditioner") = "auto", nb::kw_only(), nb::arg("sqrt_tol") = nb::none(),
           "(velocities (m, 6), RigidBodyReport): N W + noise_scale N K^T M^{-1} B z for bead noise z (N, 3)\n"
           "(standard normal, e.g. normal_noise(N, seed, step)); B B^T = M from the bead operator's sampler\n"
           "(Lanczos at sqrt_tolerance, sqrt_tol its deprecated spelling; preconditioner 'auto' | 'block' |\n"
           "'none'). The noise part has covariance\n"
           "noise_scale^2 N: with noise_scale = sqrt(2 kT / dt), Y dt is a Brownian step (without the\n"
           "thermal drift).");
}

/// RigidBodies's mobility matrix and sizes.
void add_bodies_state(BodiesClass& cls) {
  cls.def("mobility_matrix",
          locked(
              "RigidBodies.mobility_matrix",
              +[](const BoundRigidBodies& b, std::size_t max_bodies) {
                std::vector<double> n;
                {
                  nb::gil_scoped_release release;
                  n = b.bodies.mobility_matrix(max_bodies);
                }
                const std::size_t rows = 6 * b.bodies.bodies();
                return adopt_vector(std::move(n), {rows, rows});
              }),
          nb::arg("max_bodies") = 200,
          "The body mobility matrix N (6m, 6m) by 6m solves, symmetrized; kT N is the grand diffusion\n"
          "tensor (translational and rotational diffusion of bead models).")
      .def_prop_ro("bodies",
                   locked_read(
                       "RigidBodies.bodies", +[](const BoundRigidBodies& b) { return b.bodies.bodies(); }),
                   "Number of bodies m.")
      .def_prop_ro("beads",
                   locked_read(
                       "RigidBodies.beads", +[](const BoundRigidBodies& b) { return b.bodies.beads(); }),
                   "Number of beads N.")
      .def_prop_ro("reference_points",
                   locked_read(
                       "RigidBodies.reference_points",
                       +[](const BoundRigidBodies& b) { return copy_rows(b.bodies.reference_points(), 3); }),
                   "The reference points in use (m, 3).");
}

void bind_rigid_body_report(nb::module_& m) {
  nb::class_<RigidBodyReport>(m, "RigidBodyReport", "What a rigid-body mobility solve did (GMRES).")
      .def_ro("iterations", &RigidBodyReport::iterations, "GMRES iterations = bead products M lambda.")
      .def_ro("restarts", &RigidBodyReport::restarts, "GMRES restarts.")
      .def_ro("residual", &RigidBodyReport::residual,
              "Final relative residual of the saddle-point system (GMRES's recurrence estimate).")
      .def_ro("seconds_setup", &RigidBodyReport::seconds_setup, "The last set_configuration, in seconds.")
      .def_ro("seconds_solve", &RigidBodyReport::seconds_solve, "This apply's solve, in seconds.")
      .def_ro("sqrt", &RigidBodyReport::sqrt, "apply_with_noise: the SqrtReport of the bead noise B z.")
      .def_ro("seconds_sqrt", &RigidBodyReport::seconds_sqrt, "apply_with_noise: the bead noise B z, in seconds.")
      .def("__repr__", &report_repr);
}

void bind_rigid_bodies(nb::module_& m) {
  BodiesClass cls(
      m, "RigidBodies",
      "Mobility of rigid bodies made of beads (bead-shell / rigid multiblob models): forces and torques\n"
      "(m, 6) -> linear and angular velocities (m, 6), with full hydrodynamic interactions among all beads\n"
      "through a mobility operator (DirectRpy, FmmRpy, PseRpy). Solves the saddle-point system\n"
      "M lambda = K Y, K^T lambda = (F, T) by GMRES, preconditioned body by body.");
  cls.def(
      "__init__",
      [](BoundRigidBodies* self, rpy::MobilityOperator& beads, double tolerance, int max_iterations, int restart,
         bool precondition) {
        const CallGuard hold = guard("RigidBodies", beads);
        new (self) BoundRigidBodies(beads, {.tolerance = tolerance,
                                            .max_iterations = max_iterations,
                                            .restart = restart,
                                            .precondition = precondition});
      },
      nb::arg("beads"), nb::kw_only(), nb::arg("tolerance") = 1e-6, nb::arg("max_iterations") = 500,
      nb::arg("restart") = 60, nb::arg("precondition") = true, nb::keep_alive<1, 2>(),
      "beads: the bead mobility operator (kept alive; set_configuration sets its positions);\n"
      "tolerance: GMRES relative residual in (0, 1); max_iterations: bead products at most;\n"
      "restart: Krylov vectors kept; precondition: the body-block preconditioner (False: plain GMRES).");
  add_bodies_products(cls);
  add_bodies_state(cls);
}

void bind_icosphere(nb::module_& m) {
  m.def(
      "icosphere_beads",
      [](int subdivisions) {
        std::vector<double> v = rpy::icosphere_beads(subdivisions);
        const std::size_t n = v.size() / 3;
        return adopt_vector(std::move(v), {n, 3});
      },
      nb::arg("subdivisions"),
      "Bead-shell sphere: (10 4^s + 2, 3) points on the unit sphere (a subdivided icosahedron).");
  m.def("icosphere_bead_radius", &rpy::icosphere_bead_radius, nb::arg("subdivisions"),
        "Radius of touching beads on that unit shell (half the smallest bead distance).");
}

}  // namespace

void bind_rigid(nb::module_& m) {
  bind_rigid_body_report(m);
  bind_rigid_bodies(m);
  bind_icosphere(m);
}

}  // namespace rpyfmm::python
