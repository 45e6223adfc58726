// rpyfmm Python bindings — Brownian dynamics of rigid bodies of beads with whole bodies per rank
// (rpyfmm::mpi::DistributedRigidBodyDynamics, docs/mpi.md "Rigid-body Brownian dynamics across
// ranks") as rpyfmm.mpi.RigidBodyDynamics, spelled as the serial rpyfmm.RigidBodyDynamics
// (rigid_dynamics.cpp) with each rank's share of the bodies: its body-frame beads body after body,
// its body offsets from 0, its reference points and orientations.
//
// Conventions of mpi_rigid.cpp: the bead operator (a bound DistributedDirectRpy, DistributedFmmRpy or
// DistributedPseRpy, the three the C++ class takes) is kept alive by the Python object and its lock is taken with this
// object's; the arguments are checked and converted on each rank and the ranks agree on the outcome
// before the collective C++ constructor (mpi_common.hpp `agreed`), so that a bad argument on one
// rank raises on all. The force function runs under the GIL inside the C++ step's collective
// force stage (Communicator::run): a Python exception in it on one rank becomes the same
// rpyfmm Error on every rank, and every rank keeps the last good step. `pair` is the serial binding's
// bead pair potential (DistributedRigidBodyDynamics::set_bead_forces).
#include <mpi.h>
#include <nanobind/stl/string.h>

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "common.hpp"
#include "mpi_common.hpp"
#include "object_lock.hpp"
#include "rpyfmm/mpi/rigid_dynamics.hpp"

namespace rpyfmm::python {
namespace {

using Direct = WithComm<mpi::DistributedDirectRpy>;
using Fmm = WithComm<mpi::DistributedFmmRpy>;
using Pse = WithComm<mpi::DistributedPseRpy>;
using mpi::DistributedRigidBodyDynamics;

constexpr const char* kWhere = "rpyfmm.mpi.RigidBodyDynamics";

/// The Python object: the simulation, the force callable it calls and the bound bead operator it
/// drives (kept alive by the Python object; its lock is taken with this object's).
struct BoundRigidDynamics {
  nb::object forces;  ///< None or forces(time, positions (m,3), orientations (m,4), beads (n,3)) -> (m,6)
  std::variant<Direct*, Fmm*, Pse*> beads;
  std::unique_ptr<DistributedRigidBodyDynamics> sim;
};

LockPtr inner_lock_of(const BoundRigidDynamics& b) {
  return std::visit([](auto* op) { return lock_of(*op); }, b.beads);
}

/// The options the serial binding makes of the same keywords (rigid_dynamics.cpp).
struct Keywords {
  double dt, kT;
  std::uint64_t seed, first_step;
  std::string drift;
  double rfd_delta, tolerance;
  int max_iterations;
  double sqrt_tolerance;
  std::string preconditioner;
  double max_displacement;
};

bd::RigidDynamicsOptions options_of(const Keywords& k) {
  bd::RigidDrift drift = bd::RigidDrift::none;
  if (k.drift == "rfd" || k.drift == "random_finite_difference") {
    drift = bd::RigidDrift::random_finite_difference;
  } else if (k.drift != "none") {
    fail(ErrorCode::invalid_argument, kWhere, "drift must be 'rfd' or 'none', got '" + k.drift + "'");
  }
  return {.dt = k.dt,
          .kT = k.kT,
          .seed = k.seed,
          .first_step = k.first_step,
          .drift = drift,
          .rfd_delta = k.rfd_delta,
          .solver = {.tolerance = k.tolerance, .max_iterations = k.max_iterations},
          .sqrt = sqrt_options("auto", k.sqrt_tolerance, 0, true, true, 0.0, 0.0, 30, k.preconditioner, 0),
          .max_displacement = k.max_displacement};
}

/// This rank's bodies as the C++ constructor takes them.
struct LocalBodies {
  std::vector<double> shape, radii;
  std::vector<std::size_t> offsets;
  std::vector<double> positions, orientations;
  bd::RigidDynamicsOptions options;
};

std::vector<double> points_of(ArrayArg a, const std::string& name) {
  const InArray in = as_input(a, kWhere, name);
  require_points(in, kWhere, name);
  return {in.data, in.data + in.size};
}

/// Not collective: checks and converts this rank's arguments (the C++ constructor checks the
/// bodies themselves and that the options agree).
LocalBodies local_bodies_of(ArrayArg shape, RadiusArg radius, nb::handle body_offsets, ArrayArg positions,
                            OptArrayArg orientations, const Keywords& keywords) {
  LocalBodies b;
  b.shape = points_of(shape, "shape");
  b.radii = radii_from(radius, kWhere).values;  // one radius is spread over this rank's beads
  b.offsets = offsets_of(body_offsets, kWhere);
  b.positions = points_of(positions, "positions");
  if (!orientations.h.is_none()) {
    const InArray o = as_input(orientations, kWhere, "orientations");
    require(o.ndim() == 2 && o.shape[1] == 4, ErrorCode::invalid_input, kWhere,
            "orientations has shape " + shape_string(o.shape) + ", expected (m, 4) quaternions (w, x, y, z)");
    b.orientations.assign(o.data, o.data + o.size);
  }
  b.options = options_of(keywords);
  return b;
}

/// Calls `self->forces` (under the GIL: step() runs without it) on this rank's bodies. A Python
/// exception becomes an rpyfmm Error naming it, which the C++ force stage agrees over the ranks.
void call_forces(const BoundRigidDynamics* self, const bd::RigidBodyState& state, std::span<double> w) {
  nb::gil_scoped_acquire acquire;
  const std::string name = std::string(kWhere) + " forces";
  nb::object result;
  try {
    // Copies the callable may keep.
    result = self->forces(state.time, copy_rows(state.positions, 3).o, copy_rows(state.orientations, 4).o,
                          copy_rows(state.bead_positions, 3).o);
  } catch (nb::python_error& e) {
    fail(ErrorCode::invalid_input, name, std::string("the forces function raised ") + e.what());
  }
  const InArray f = as_input(ArrayArg{result}, name, "the forces function's result");
  require(f.size == w.size(), ErrorCode::invalid_input, name,
          "the forces function returned shape " + shape_string(f.shape) + ", expected (m, 6) = (" +
              std::to_string(w.size() / 6) + ", 6)");
  std::copy(f.data, f.data + f.size, w.begin());
}

/// Collective: the serial binding's bead pair potential `pair` (rigid_dynamics.cpp: None, or one bead
/// type with the radius of the first bead in the global order, so a sigma of 0 is twice it) on `sim`.
/// `first_radius`: this rank's first bead's radius (any value on a rank without beads).
void add_bead_pair(const mpi::Communicator& comm, DistributedRigidBodyDynamics& sim, nb::handle pair,
                   double first_radius) {
  comm.run([&] {
    require(mpi::same_on_every_rank(comm, {pair.is_none() ? 0.0 : 1.0}), ErrorCode::invalid_argument, kWhere,
            "pair must be given on every rank or on none");
  });
  if (pair.is_none()) return;
  const double mine = sim.first_bead() == 0 && sim.local_beads() > 0 ? first_radius : 0.0;  // radii are > 0
  double radius = 0.0;
  mpi::check_mpi(MPI_Allreduce(&mine, &radius, 1, MPI_DOUBLE, MPI_MAX, comm.get()), "MPI_Allreduce");
  bd::ForceField field = agreed(comm, [&] {
    bd::ForceField f({bd::ParticleType{.radius = radius}});
    f.set_pair(0, 0, pair_from(pair, kWhere));
    return f;
  });
  nb::gil_scoped_release release;
  sim.set_bead_forces(std::move(field));
}

/// __init__ for a bead operator of type Op: collective.
template <class Op>
void init(BoundRigidDynamics* self, WithComm<Op>& beads, ArrayArg shape, RadiusArg radius, nb::handle body_offsets,
          ArrayArg positions, OptArrayArg orientations, const Keywords& keywords, nb::object forces, nb::handle pair) {
  const CallGuard hold = guard(kWhere, beads);
  const mpi::Communicator& comm = beads.op.communicator();
  LocalBodies b = agreed(comm, [&] {
    require(forces.is_none() || PyCallable_Check(forces.ptr()), ErrorCode::invalid_argument, kWhere,
            "forces must be None or a callable forces(time, positions, orientations, bead_positions) -> (m, 6)");
    return local_bodies_of(shape, radius, body_offsets, positions, orientations, keywords);
  });
  bd::BodyForceFunction function;
  if (!forces.is_none()) {
    // `self` is constructed below, before any step calls this.
    function = [self](const bd::RigidBodyState& state, std::span<double> w) { call_forces(self, state, w); };
  }
  const double first_radius = b.radii.empty() ? 0.0 : b.radii.front();
  std::unique_ptr<DistributedRigidBodyDynamics> sim;
  {
    nb::gil_scoped_release release;
    sim = std::make_unique<DistributedRigidBodyDynamics>(beads.op, std::move(b.shape), std::move(b.radii),
                                                         std::move(b.offsets), std::move(b.positions),
                                                         std::move(b.orientations), b.options, std::move(function));
  }
  add_bead_pair(comm, *sim, pair, first_radius);
  new (self) BoundRigidDynamics{std::move(forces), &beads, std::move(sim)};
}

/// Steps without the GIL (the force function takes it while it runs).
bd::RigidStepReport run(BoundRigidDynamics& self, std::uint64_t steps) {
  nb::gil_scoped_release release;
  self.sim->run(steps);
  return self.sim->last_report();
}

using DynamicsClass = nb::class_<BoundRigidDynamics>;

template <class Op>
void add_init(DynamicsClass& cls) {
  cls.def(
      "__init__",
      [](BoundRigidDynamics* self, WithComm<Op>& beads, ArrayArg shape, RadiusArg radius, nb::handle body_offsets,
         ArrayArg positions, OptArrayArg orientations, double dt, double kT, std::uint64_t seed,
         std::uint64_t first_step, const std::string& drift, double rfd_delta, double tolerance, int max_iterations,
         double sqrt_tolerance, const std::string& preconditioner, double max_displacement, nb::object forces,
         nb::handle pair) {
        init(self, beads, shape, radius, body_offsets, positions, orientations,
             Keywords{dt, kT, seed, first_step, drift, rfd_delta, tolerance, max_iterations, sqrt_tolerance,
                      preconditioner, max_displacement},
             std::move(forces), pair);
      },
      nb::arg("beads"), nb::arg("shape"), nb::arg("radius"), nb::arg("body_offsets").none(), nb::arg("positions"),
      nb::arg("orientations") = nb::none(), nb::kw_only(), nb::arg("dt"), nb::arg("kT") = 1.0, nb::arg("seed") = 1,
      nb::arg("first_step") = 0, nb::arg("drift") = "rfd", nb::arg("rfd_delta") = 1e-3, nb::arg("tolerance") = 1e-6,
      nb::arg("max_iterations") = 500, nb::arg("sqrt_tolerance") = 1e-3, nb::arg("preconditioner") = "auto",
      nb::arg("max_displacement") = 1.0, nb::arg("forces") = nb::none(), nb::arg("pair") = nb::none(),
      nb::keep_alive<1, 2>(),
      "Collective. beads: a DistributedDirectRpy, DistributedFmmRpy or DistributedPseRpy (kept alive; in\n"
      "its periodic box nothing is wrapped, lever arms are minimum images, the noise is its split sampler\n"
      "and preconditioner='block' is refused); this rank's bodies as\n"
      "rpyfmm.RigidBodyDynamics takes all of them: shape (n, 3) body-frame beads, body after body (n may\n"
      "be 0); radius: a number or (n,) radii; body_offsets: m + 1 increasing indices (first 0, last n;\n"
      "[0] on a rank without bodies); positions (m, 3); orientations (m, 4) (w, x, y, z) or None\n"
      "(identity). The global body order is the ranks' bodies in rank order. The keywords are\n"
      "rpyfmm.RigidBodyDynamics's and must be the same on every rank; pair (as rpyfmm.RigidBodyDynamics's:\n"
      "between beads of different bodies on all ranks, one bead type of the first bead's radius in the\n"
      "global order) is summed on each rank's beads in the serial order (docs/mpi.md).\n"
      "forces: None or forces(time, positions (m,3), orientations (m,4), bead_positions (n,3)) -> (m, 6)\n"
      "of this rank's bodies, called on every rank (also one without bodies) in every step; an exception\n"
      "in it raises rpyfmm.InvalidInputError on every rank. A bad argument on any rank raises on every rank.");
}

void add_steps(DynamicsClass& cls) {
  cls.def("step",
          locked(
              "rpyfmm.mpi.RigidBodyDynamics.step", +[](BoundRigidDynamics& self) { return run(self, 1); }),
          "Collective. One step; returns its RigidStepReport (the same iterations on every rank). On a\n"
          "blow-up, a force error or an unconverged solve on any rank every rank keeps the last good step\n"
          "and raises.")
      .def("run", locked("rpyfmm.mpi.RigidBodyDynamics.run", &run), nb::arg("steps"),
           "Collective. Advances `steps` steps; returns the last step's RigidStepReport.");
}

/// This rank's bodies and beads (owning copies: the arrays of the C++ object change every step).
void add_local_state(DynamicsClass& cls) {
  cls.def_prop_ro(
         "comm", [](const BoundRigidDynamics& b) { return std::visit([](auto* op) { return op->comm; }, b.beads); },
         "The mpi4py communicator of the bead operator.")
      .def_prop_ro("positions",
                   locked_read(
                       "rpyfmm.mpi.RigidBodyDynamics.positions",
                       +[](BoundRigidDynamics& s) { return copy_rows(s.sim->local_positions(), 3); }),
                   "This rank's reference points (m, 3), unwrapped.")
      .def_prop_ro("orientations",
                   locked_read(
                       "rpyfmm.mpi.RigidBodyDynamics.orientations",
                       +[](BoundRigidDynamics& s) { return copy_rows(s.sim->local_orientations(), 4); }),
                   "This rank's unit quaternions (m, 4) (w, x, y, z).")
      .def_prop_ro("bead_positions",
                   locked_read(
                       "rpyfmm.mpi.RigidBodyDynamics.bead_positions",
                       +[](BoundRigidDynamics& s) { return copy_rows(s.sim->local_bead_positions(), 3); }),
                   "This rank's bead positions (n, 3) = q_k + R_k rho_i, unwrapped.")
      .def_prop_ro("lever_arms",
                   locked_read(
                       "rpyfmm.mpi.RigidBodyDynamics.lever_arms",
                       +[](BoundRigidDynamics& s) {
                         const auto l = s.sim->local_lever_arms();
                         return adopt_vector(std::vector<double>(l.begin(), l.end()), {l.size()});
                       }),
                   "This rank's bodies' RMS lever arms (m,).")
      .def_prop_ro("local_bodies",
                   locked_read(
                       "rpyfmm.mpi.RigidBodyDynamics.local_bodies",
                       +[](BoundRigidDynamics& s) { return s.sim->local_bodies(); }),
                   "This rank's number of bodies m.")
      .def_prop_ro(
          "local_beads",
          locked_read(
              "rpyfmm.mpi.RigidBodyDynamics.local_beads", +[](BoundRigidDynamics& s) { return s.sim->local_beads(); }),
          "This rank's number of beads n.")
      .def_prop_ro(
          "first_body",
          locked_read(
              "rpyfmm.mpi.RigidBodyDynamics.first_body", +[](BoundRigidDynamics& s) { return s.sim->first_body(); }),
          "The global index of this rank's first body.")
      .def_prop_ro(
          "first_bead",
          locked_read(
              "rpyfmm.mpi.RigidBodyDynamics.first_bead", +[](BoundRigidDynamics& s) { return s.sim->first_bead(); }),
          "The global index of this rank's first bead.");
}

/// What every rank shares: the number of bodies, the step, the last report and the totals.
void add_shared_state(DynamicsClass& cls) {
  cls.def_prop_ro("bodies",
                  locked_read(
                      "rpyfmm.mpi.RigidBodyDynamics.bodies", +[](BoundRigidDynamics& s) { return s.sim->bodies(); }),
                  "The number of bodies on all ranks.")
      .def_prop_ro("time",
                   locked_read(
                       "rpyfmm.mpi.RigidBodyDynamics.time", +[](BoundRigidDynamics& s) { return s.sim->time(); }),
                   "step_count * dt (time units).")
      .def_prop_ro(
          "step_count",
          locked_read(
              "rpyfmm.mpi.RigidBodyDynamics.step_count", +[](BoundRigidDynamics& s) { return s.sim->step_count(); }),
          "Step number of the current state (first_step + steps taken), the same on every rank.")
      .def_prop_ro(
          "last_report",
          locked_read(
              "rpyfmm.mpi.RigidBodyDynamics.last_report", +[](BoundRigidDynamics& s) { return s.sim->last_report(); }),
          "The RigidStepReport of the last step (iterations: the same on every rank).")
      .def_prop_ro("totals",
                   locked_read(
                       "rpyfmm.mpi.RigidBodyDynamics.totals",
                       +[](BoundRigidDynamics& s) { return rigid_totals_dict(s.sim->totals()); }),
                   "Counters (the same on every rank) and this rank's seconds per stage ('forces', 'plan',\n"
                   "'sqrt', 'solve', 'drift', 'update').");
}

}  // namespace

void bind_mpi_rigid_dynamics(nb::module_& m) {
  DynamicsClass cls(
      m, "RigidBodyDynamics",
      "Brownian dynamics of rigid bodies made of beads, whole bodies per rank: rpyfmm.RigidBodyDynamics's\n"
      "step with the solves across the ranks (docs/mpi.md). With DistributedDirectRpy and\n"
      "preconditioner='none' its trajectory differs from rpyfmm.RigidBodyDynamics's with DirectRpy only\n"
      "by the order of GMRES's inner-product sums (bit for bit on one rank); with DistributedPseRpy it is\n"
      "rpyfmm.RigidBodyDynamics's with PseRpy (double wave grids) to round-off.");
  add_init<mpi::DistributedDirectRpy>(cls);
  add_init<mpi::DistributedFmmRpy>(cls);
  add_init<mpi::DistributedPseRpy>(cls);
  add_steps(cls);
  add_local_state(cls);
  add_shared_state(cls);
}

}  // namespace rpyfmm::python
