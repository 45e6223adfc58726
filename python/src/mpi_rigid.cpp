// rpyfmm Python bindings — rigid bodies of beads with the bodies distributed over the ranks
// (rpyfmm::mpi::DistributedRigidBodies, docs/mpi.md "Rigid bodies across ranks") as
// rpyfmm.mpi.DistributedRigidBodies, spelled as the serial rpyfmm.RigidBodies (rigid.cpp) with each
// rank's share of the bodies: its beads body after body, its body offsets from 0, its bodies'
// forces and torques.
//
// The bead operator (a bound DistributedDirectRpy, DistributedFmmRpy or DistributedPseRpy) is kept alive by the
// Python object (keep_alive), since the C++ object only points to it, and every call also takes
// the operator's lock (object_lock.hpp), as RigidBodies does. Every call is collective; its
// arguments are checked and converted on each rank and the ranks agree on the outcome before the
// collective C++ call (mpi_common.hpp `agreed`), so that a bad argument on one rank raises on all.
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <cmath>
#include <cstddef>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "common.hpp"
#include "mpi_common.hpp"
#include "object_lock.hpp"
#include "rpyfmm/mpi/rigid_bodies.hpp"

namespace rpyfmm::python {
namespace {

using Direct = WithComm<mpi::DistributedDirectRpy>;
using Fmm = WithComm<mpi::DistributedFmmRpy>;
using Pse = WithComm<mpi::DistributedPseRpy>;
using rpy::RigidBodyReport;

/// The Python DistributedRigidBodies: the solver and the bound bead operator it drives (kept alive
/// by the Python object), whose lock every call takes too.
struct BoundDistributedRigid {
  template <class Op>
  BoundDistributedRigid(WithComm<Op>& op, const rpy::RigidBodyOptions& options) : beads(&op), bodies(op.op, options) {}
  std::variant<Direct*, Fmm*, Pse*> beads;
  mpi::DistributedRigidBodies bodies;
};

LockPtr inner_lock_of(const BoundDistributedRigid& b) {
  return std::visit([](auto* op) { return lock_of(*op); }, b.beads);
}

/// Checks forces_torques: (m, 6) or (6m,) (the sizes are the C++ call's collective check).
InArray forces_torques_of(ArrayArg forces_torques, const std::string& where) {
  InArray w = as_input(forces_torques, where, "forces_torques");
  require_body_rows(w, where, "forces_torques");
  return w;
}

void set_configuration(BoundDistributedRigid& bound, ArrayArg positions, RadiusArg radius, nb::handle body_offsets,
                       OptArrayArg reference_points) {
  const std::string where = "DistributedRigidBodies.set_configuration";
  struct Args {
    InArray x;
    std::vector<double> radii;
    std::vector<std::size_t> offsets;
    InArray q;
  };
  const Args a = agreed(bound.bodies.communicator(), [&] {
    Args r;
    r.x = as_input(positions, where, "positions");
    const std::size_t n = require_points(r.x, where, "positions");
    if (!reference_points.h.is_none()) {
      r.q = as_input(reference_points, where, "reference_points");
      require_points(r.q, where, "reference_points");
    }
    const Radii radii = radii_from(radius, where);
    r.radii = radii.scalar ? std::vector<double>(n, radii.values[0]) : radii.values;
    r.offsets = offsets_of(body_offsets, where);
    return r;
  });
  nb::gil_scoped_release release;
  bound.bodies.set_configuration(a.x.span(), a.radii, a.offsets, a.q.span());
}

/// (velocities (m, 6)[, bead forces (n, 3)], report) for this rank's bodies and beads.
nb::tuple apply(const BoundDistributedRigid& bound, ArrayArg forces_torques, bool with_bead_forces) {
  const std::string where = "DistributedRigidBodies.apply";
  const mpi::DistributedRigidBodies& bodies = bound.bodies;
  struct Args {
    InArray w;
    OutArray y;
  };
  const Args a = agreed(bodies.communicator(), [&] {
    InArray w = forces_torques_of(forces_torques, where);
    return Args{std::move(w), make_output(nb::none(), {bodies.local_bodies(), 6}, where)};
  });
  std::vector<double> lambda(with_bead_forces ? 3 * bodies.local_beads() : 0);
  RigidBodyReport report;
  {
    nb::gil_scoped_release release;
    report = bodies.apply(a.w.span(), a.y.span(), lambda);
  }
  if (!with_bead_forces) return nb::make_tuple(a.y.object, report);
  const std::size_t n = bodies.local_beads();
  return nb::make_tuple(a.y.object, adopt_vector(std::move(lambda), {n, 3}).o, report);
}

/// (velocities (m, 6), bead forces (n, 3), report) for this rank's bodies and beads, GMRES started
/// from this rank's guesses (the C++ call checks their sizes and values collectively).
nb::tuple apply_from(const BoundDistributedRigid& bound, ArrayArg forces_torques, ArrayArg guess_velocities,
                     ArrayArg guess_bead_forces) {
  const std::string where = "DistributedRigidBodies.apply_from";
  const mpi::DistributedRigidBodies& bodies = bound.bodies;
  struct Args {
    InArray w, gy, gl;
    OutArray y;
  };
  const Args a = agreed(bodies.communicator(), [&] {
    Args r{forces_torques_of(forces_torques, where), as_input(guess_velocities, where, "guess_velocities"),
           as_input(guess_bead_forces, where, "guess_bead_forces"), OutArray{}};
    require_body_rows(r.gy, where, "guess_velocities");
    require_points(r.gl, where, "guess_bead_forces");
    r.y = make_output(nb::none(), {bodies.local_bodies(), 6}, where);
    return r;
  });
  std::vector<double> lambda(3 * bodies.local_beads());
  RigidBodyReport report;
  {
    nb::gil_scoped_release release;
    report = bodies.apply_from(a.w.span(), a.gy.span(), a.gl.span(), a.y.span(), lambda);
  }
  return nb::make_tuple(a.y.object, adopt_vector(std::move(lambda), {bodies.local_beads(), 3}).o, report);
}

/// (velocities (m, 6), report): N W + noise_scale N K^T M^{-1} B z for this rank's bead noise z.
nb::tuple apply_with_noise(const BoundDistributedRigid& bound, ArrayArg forces_torques, double noise_scale, ArrayArg z,
                           std::optional<double> sqrt_tolerance, const std::string& preconditioner) {
  const std::string where = "DistributedRigidBodies.apply_with_noise";
  const mpi::DistributedRigidBodies& bodies = bound.bodies;
  struct Args {
    InArray w;
    InArray z;
    rpy::SqrtOptions options;
    OutArray y;
  };
  const Args a = agreed(bodies.communicator(), [&] {
    InArray w = forces_torques_of(forces_torques, where);
    InArray zz = as_input(z, where, "z");
    require_points(zz, where, "z");
    // The serial RigidBodies.apply_with_noise's sampler options (rigid.cpp).
    rpy::SqrtOptions o =
        sqrt_options("auto", sqrt_tolerance.value_or(1e-3), 0, true, true, 0.0, 0.0, 30, preconditioner, 0);
    return Args{std::move(w), std::move(zz), o, make_output(nb::none(), {bodies.local_bodies(), 6}, where)};
  });
  RigidBodyReport report;
  {
    nb::gil_scoped_release release;
    report = bodies.apply_with_noise(a.w.span(), noise_scale, a.z.span(), a.y.span(), a.options);
  }
  return nb::make_tuple(a.y.object, report);
}

/// The whole body mobility matrix (6m, 6m) on every rank (collective, refusals agreed in C++).
ArrayResult mobility_matrix(const BoundDistributedRigid& bound, std::size_t max_bodies) {
  std::vector<double> n;
  {
    nb::gil_scoped_release release;
    n = bound.bodies.mobility_matrix(max_bodies);
  }
  auto rows = static_cast<std::size_t>(std::llround(std::sqrt(static_cast<double>(n.size()))));
  return adopt_vector(std::move(n), {rows, rows});
}

using RigidClass = nb::class_<BoundDistributedRigid>;

/// __init__ for a bead operator of type Op: collective (the C++ constructor agrees on the options).
template <class Op>
void add_init(RigidClass& cls) {
  cls.def(
      "__init__",
      [](BoundDistributedRigid* self, WithComm<Op>& beads, double tolerance, int max_iterations, int restart,
         bool precondition) {
        const CallGuard hold = guard("DistributedRigidBodies", beads);
        const rpy::RigidBodyOptions options{
            .tolerance = tolerance, .max_iterations = max_iterations, .restart = restart, .precondition = precondition};
        nb::gil_scoped_release release;
        new (self) BoundDistributedRigid(beads, options);
      },
      nb::arg("beads"), nb::kw_only(), nb::arg("tolerance") = 1e-6, nb::arg("max_iterations") = 500,
      nb::arg("restart") = 60, nb::arg("precondition") = true, nb::keep_alive<1, 2>(),
      "Collective. beads: a DistributedDirectRpy, DistributedFmmRpy or DistributedPseRpy (periodic box: lever\n"
      "arms are minimum images; equal radii) (kept alive; set_configuration sets its positions); tolerance: GMRES "
      "relative residual in (0, 1); max_iterations: bead products at most;\n"
      "restart: Krylov vectors kept; precondition: the body-block preconditioner. Every rank must pass the\n"
      "same values (else every rank raises).");
}

void add_products(RigidClass& cls) {
  cls.def("set_configuration", locked("DistributedRigidBodies.set_configuration", &set_configuration),
          nb::arg("positions"), nb::arg("radius"), nb::arg("body_offsets").none(),
          nb::arg("reference_points") = nb::none(),
          "Collective. This rank's beads (n, 3), body after body (n may be 0); radius: a number or (n,) radii;\n"
          "body_offsets: m + 1 increasing indices into this rank's beads (first 0, last n; [0] on a rank\n"
          "without bodies); reference_points: (m, 3) (None: each body's bead centroid). The global bead\n"
          "order is the ranks' beads in rank order.")
      .def("apply",
           locked(
               "DistributedRigidBodies.apply",
               +[](const BoundDistributedRigid& b, ArrayArg w) { return apply(b, w, false); }),
           nb::arg("forces_torques"),
           "Collective. (velocities (m, 6), RigidBodyReport) of this rank's bodies for their forces_torques\n"
           "(m, 6), as RigidBodies.apply.")
      .def("apply_with_bead_forces",
           locked(
               "DistributedRigidBodies.apply_with_bead_forces",
               +[](const BoundDistributedRigid& b, ArrayArg w) { return apply(b, w, true); }),
           nb::arg("forces_torques"),
           "Collective. (velocities (m, 6), bead forces (n, 3), RigidBodyReport) of this rank's bodies and beads.")
      .def("apply_from", locked("DistributedRigidBodies.apply_from", &apply_from), nb::arg("forces_torques"),
           nb::arg("guess_velocities"), nb::arg("guess_bead_forces"),
           "Collective. (velocities (m, 6), bead forces (n, 3), RigidBodyReport) of this rank's bodies and\n"
           "beads, as RigidBodies.apply_from: GMRES started from this rank's share of a guess,\n"
           "guess_velocities (m, 6) and guess_bead_forces (n, 3) (a bad guess on any rank raises on every rank).")
      .def("apply_with_noise", locked("DistributedRigidBodies.apply_with_noise", &apply_with_noise),
           nb::arg("forces_torques"), nb::arg("noise_scale"), nb::arg("z"),
           nb::arg("sqrt_tolerance").sig("0.001") = nb::none(), nb::arg("preconditioner") = "auto",
           "Collective. (velocities (m, 6), RigidBodyReport): as RigidBodies.apply_with_noise, z this rank's\n"
           "beads' noise (n, 3) (rpyfmm.mpi.normal_noise with the bead operator's offset draws the serial\n"
           "noise's rows); B z by rpyfmm.mpi's Lanczos sampler across the ranks at sqrt_tolerance ('auto' is\n"
           "'none' across ranks, the serial order of sums; 'block' the serial blocks of all ranks' beads), with\n"
           "DistributedPseRpy by its split sampler, as RigidBodies with PseRpy ('block' refused).")
      .def("mobility_matrix", locked("DistributedRigidBodies.mobility_matrix", &mobility_matrix),
           nb::arg("max_bodies") = 200,
           "Collective. The body mobility matrix N (6m, 6m) of all ranks' bodies (m in all, in rank order),\n"
           "the same on every rank, as RigidBodies.mobility_matrix: 6m solves, symmetrized.");
}

void add_state(RigidClass& cls) {
  cls.def_prop_ro(
         "comm", [](const BoundDistributedRigid& b) { return std::visit([](auto* op) { return op->comm; }, b.beads); },
         "The mpi4py communicator of the bead operator.")
      .def_prop_ro("local_bodies",
                   locked_read(
                       "DistributedRigidBodies.local_bodies",
                       +[](const BoundDistributedRigid& b) { return b.bodies.local_bodies(); }),
                   "This rank's number of bodies m (0 before set_configuration).")
      .def_prop_ro("local_beads",
                   locked_read(
                       "DistributedRigidBodies.local_beads",
                       +[](const BoundDistributedRigid& b) { return b.bodies.local_beads(); }),
                   "This rank's number of beads n (0 before set_configuration).")
      .def_prop_ro("reference_points",
                   locked_read(
                       "DistributedRigidBodies.reference_points",
                       +[](const BoundDistributedRigid& b) { return copy_rows(b.bodies.local_reference_points(), 3); }),
                   "The reference points in use of this rank's bodies (m, 3).");
}

}  // namespace

std::vector<std::size_t> offsets_of(nb::handle body_offsets, const std::string& where) {
  std::vector<std::size_t> offsets;
  if (!nb::try_cast(body_offsets, offsets)) {
    fail(ErrorCode::invalid_input, where,
         "body_offsets must be a sequence of non-negative integers, got " +
             std::string(nb::type_name(body_offsets.type()).c_str()));
  }
  return offsets;
}

void bind_mpi_rigid(nb::module_& m) {
  RigidClass cls(m, "DistributedRigidBodies",
                 "Mobility of rigid bodies made of beads, the bodies distributed over the ranks (whole bodies per\n"
                 "rank): rpyfmm.RigidBodies's saddle-point GMRES with the bead products M lambda across the ranks\n"
                 "(docs/mpi.md). With DistributedDirectRpy its results differ from RigidBodies with DirectRpy on\n"
                 "the whole set only by the order of GMRES's inner-product sums (bit for bit on one rank).");
  add_init<mpi::DistributedDirectRpy>(cls);
  add_init<mpi::DistributedFmmRpy>(cls);
  add_init<mpi::DistributedPseRpy>(cls);
  add_products(cls);
  add_state(cls);
  bind_mpi_rigid_dynamics(m);
}

}  // namespace rpyfmm::python
