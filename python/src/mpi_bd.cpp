// rpyfmm Python bindings — Brownian dynamics across the ranks of an mpi4py communicator, step by
// step: rpyfmm.mpi.Simulation around rpyfmm::mpi::DistributedBd (docs/mpi.md, "Brownian dynamics
// across ranks" and "Python (mpi4py)"), the counterpart of rpyfmm.Simulation.from_config (bd.cpp).
//
// A config becomes the run `mpirun rpyfmm bd` takes (rpyfmm/mpi/bd_stepper.hpp): the same force
// field, particles and bonds on every rank, rank r starting with the block [r N / P, (r + 1) N / P)
// of global indices; the first step's rebuild then partitions them along the Morton curve. So with
// free draining the positions after every step are rpyfmm.Simulation's bit for bit.
//
// Conventions of mpi.cpp: every method that talks to the other ranks is collective (all ranks call
// it in the same order), argument checks are agreed over the ranks before a collective C++ call
// (a bad config on one rank raises the same exception on every rank), the GIL is released in the
// collective C++ calls, and calls on one object are serialized by its lock (object_lock.hpp).
// Arrays of this rank's particles are copies that own their memory: a step moves particles between
// ranks and reallocates DistributedBd's arrays, so a view could dangle, and a copy keeps the step
// it was read at.
#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "mpi_common.hpp"
#include "object_lock.hpp"
#include "rpyfmm/bd/config.hpp"
#include "rpyfmm/bd/force_field.hpp"
#include "rpyfmm/bd/particles.hpp"
#include "rpyfmm/mpi/bd_stepper.hpp"
#include "rpyfmm/mpi/brownian_dynamics.hpp"
#include "run_arguments.hpp"

namespace rpyfmm::python {
namespace {

constexpr const char* kWhere = "rpyfmm.mpi.Simulation";

/// DistributedBd and the mpi4py communicator it works on (declared first: released after it).
struct DistributedSimulation {
  nb::object comm;
  std::unique_ptr<mpi::DistributedBd> bd;
};

/// What a DistributedBd is made from: the config's force field (with its bonds), options and this
/// rank's block of the initial particles.
struct BdStart {
  bd::ForceField forces;
  rpy::Geometry geometry;
  mpi::DistributedBdOptions options;
  mpi::BdShare share;
};

/// Not collective: the start of `config`'s run and this rank's block of its particles.
BdStart start_of(const bd::RunConfig& config, const mpi::Communicator& world) {
  bd::ForceField forces = bd::make_force_field(config);
  const bd::InitialState init = bd::make_particles(config, forces);
  forces.add_bonds(init.bonds);
  mpi::BdShare share = mpi::block_share(world.rank(), world.size(), init.positions, init.types,
                                        config.integrator.rotation, init.orientations);
  return BdStart{std::move(forces), config.geometry, mpi::distributed_bd_options(config), std::move(share)};
}

void init_simulation(DistributedSimulation* self, nb::object comm, nb::handle config) {
  const MPI_Comm handle = comm_from(comm, kWhere);
  const mpi::Communicator world(handle);
  BdStart s = agreed(world, [&] { return start_of(config_from(config), world); });
  std::unique_ptr<mpi::DistributedBd> made;
  {
    nb::gil_scoped_release release;
    made = std::make_unique<mpi::DistributedBd>(handle, std::move(s.forces), s.geometry, std::move(s.options),
                                                std::move(s.share));
  }
  new (self) DistributedSimulation{std::move(comm), std::move(made)};
}

/// A copy (values.size() / per, per) of this rank's values that owns its memory.
ArrayResult copy_of(std::span<const double> values, std::size_t per) {
  return adopt_vector(std::vector<double>(values.begin(), values.end()), {values.size() / per, per});
}

/// Collective: the whole state in global index order on `root` as a dict; None on the other ranks.
nb::object gather(const DistributedSimulation& s, int root) {
  const mpi::Communicator& world = s.bd->communicator();
  agreed(world, [&] {
    require(root >= 0 && root < world.size(), ErrorCode::invalid_argument, "gather",
            "root " + std::to_string(root) + " is not a rank of the communicator (size " +
                std::to_string(world.size()) + ")");
    return 0;
  });
  bd::Checkpoint c;
  {
    nb::gil_scoped_release release;
    c = s.bd->checkpoint(root);
  }
  if (world.rank() != root) return nb::none();
  const std::size_t n = c.types.size(), rotated = c.orientations.size() / 4, inertial = c.velocities.size() / 3;
  nb::dict d;
  d["step"] = c.step;
  d["positions"] = adopt_vector(std::move(c.positions), {n, 3}).o;
  d["reference_positions"] = adopt_vector(std::move(c.reference_positions), {n, 3}).o;
  d["types"] = adopt_integers(std::move(c.types));
  d["orientations"] = adopt_vector(std::move(c.orientations), {rotated, 4}).o;
  d["velocities"] = adopt_vector(std::move(c.velocities), {inertial, 3}).o;
  return d;
}

nb::dict stats_dict(const mpi::DistributedBdStats& t) {
  nb::dict d;
  d["steps"] = t.steps;
  d["rebuilds"] = t.rebuilds;
  d["repartitions"] = t.repartitions;
  d["halo_size"] = t.halo_size;
  d["imbalance"] = t.imbalance;
  d["seconds"] = t.seconds;
  return d;
}

using Sim = DistributedSimulation;
using SimClass = nb::class_<Sim>;

void add_steps(SimClass& cls) {
  cls.def("step",
          locked(
              "Simulation.step",
              +[](Sim& s) {
                nb::gil_scoped_release release;
                s.bd->step();
              }),
          "Collective. Advances one step; on a blow-up or a hard-core overlap on any rank every rank raises\n"
          "the same exception (naming the particle by its global index) and the state stays at the last good\n"
          "step.")
      .def("run",
           locked(
               "Simulation.run",
               +[](Sim& s, std::uint64_t count) {
                 nb::gil_scoped_release release;
                 s.bd->run(count);
               }),
           nb::arg("count"), "Collective. Advances `count` steps.")
      .def("gather", locked_read("Simulation.gather", &gather), nb::arg("root") = 0,
           "Collective. The whole system in global index order on rank `root` as a dict: 'step', 'positions'\n"
           "(N, 3), 'reference_positions' (N, 3, at step 0), 'types' (N,), 'orientations' (N, 4; (0, 4)\n"
           "without rotation), 'velocities' (N, 3; (0, 3) without inertial types); None on the other ranks.")
      .def("rotation_moments",
           locked_read(
               "Simulation.rotation_moments",
               +[](const Sim& s) {
                 std::array<double, 2> m{};
                 {
                   nb::gil_scoped_release release;
                   m = s.bd->rotation_moments();
                 }
                 return nb::make_tuple(m[0], m[1]);
               }),
           "Collective, with rotation: (rotational MSD, orientation correlation) over every rank's particles,\n"
           "the serial log's columns to round-off; InvalidArgumentError without rotation.")
      .def("kinetic_temperature",
           locked_read(
               "Simulation.kinetic_temperature",
               +[](const Sim& s) {
                 nb::gil_scoped_release release;
                 return s.bd->kinetic_temperature();
               }),
           "Collective: the kinetic temperature of every rank's inertial particles (0 without).");
}

/// This rank's particles (copies owning their memory, in increasing global index).
void add_share(SimClass& cls) {
  cls.def_prop_ro("positions",
                  locked_read(
                      "Simulation.positions", +[](const Sim& s) { return copy_of(s.bd->positions(), 3); }),
                  "This rank's unwrapped positions (n, 3), a copy (a step moves particles between ranks).")
      .def_prop_ro("last_forces",
                   locked_read(
                       "Simulation.last_forces", +[](const Sim& s) { return copy_of(s.bd->last_forces(), 3); }),
                   "The forces (n, 3) on this rank's particles at the start of the last step (0 before the first\n"
                   "and after a repartition until the next step), a copy.")
      .def_prop_ro("orientations",
                   locked_read(
                       "Simulation.orientations", +[](const Sim& s) { return copy_of(s.bd->orientations(), 4); }),
                   "This rank's orientations (n, 4), unit quaternions (w, x, y, z), with [system] rotation = true;\n"
                   "shape (0, 4) without rotation. A copy.")
      .def_prop_ro("velocities",
                   locked_read(
                       "Simulation.velocities", +[](const Sim& s) { return copy_of(s.bd->velocities(), 3); }),
                   "This rank's half-step velocities (n, 3) with inertial (Langevin) types (0 for Brownian\n"
                   "particles); shape (0, 3) without. A copy.")
      .def_prop_ro("ids",
                   locked_read(
                       "Simulation.ids", +[](const Sim& s) { return copy_integers(s.bd->ids()); }),
                   "The global indices (n,) of this rank's particles, increasing: the partition, which changes\n"
                   "at rebuilds (Morton-curve ranges, docs/mpi.md). A copy.")
      .def_prop_ro("types",
                   locked_read(
                       "Simulation.types", +[](const Sim& s) { return copy_integers(s.bd->types()); }),
                   "The type indices (n,) of this rank's particles (the config's [[types]] order). A copy.")
      .def_prop_ro("local_size",
                   locked_read(
                       "Simulation.local_size", +[](const Sim& s) { return s.bd->local_size(); }),
                   "This rank's number of particles n.");
}

/// Counters and values the same on every rank (not collective).
void add_counters(SimClass& cls) {
  cls.def_prop_ro(
         "comm", [](const Sim& s) { return s.comm; }, "The mpi4py communicator the simulation works on.")
      .def_prop_ro(
          "global_size", [](const Sim& s) { return s.bd->global_size(); }, "The number of particles on all ranks N.")
      .def_prop_ro(
          "size", [](const Sim& s) { return s.bd->global_size(); }, "N, as rpyfmm.Simulation.size.")
      .def_prop_ro("step_count",
                   locked_read(
                       "Simulation.step_count", +[](const Sim& s) { return s.bd->step_count(); }),
                   "Number of the current step.")
      .def_prop_ro(
          "time",
          locked_read(
              "Simulation.time",
              +[](const Sim& s) { return static_cast<double>(s.bd->step_count()) * s.bd->options().integrator.dt; }),
          "step_count * dt.")
      .def_prop_ro(
          "dt", [](const Sim& s) { return s.bd->options().integrator.dt; }, "Time step (time units).")
      .def_prop_ro(
          "kT", [](const Sim& s) { return s.bd->options().integrator.kT; }, "Thermal energy (energy units).")
      .def_prop_ro(
          "mobility", [](const Sim& s) { return std::string(rpy::to_string(s.bd->options().method)); },
          "The mobility across ranks: 'none', 'direct', 'fmm' or 'pse' (a config's 'auto' resolved).")
      .def_prop_ro("potential_energy",
                   locked_read(
                       "Simulation.potential_energy", +[](const Sim& s) { return s.bd->potential_energy(); }),
                   "The potential energy at the start of the last step summed over the ranks (0 before a step);\n"
                   "the same on every rank, the serial value to round-off.")
      .def_prop_ro("stats",
                   locked_read(
                       "Simulation.stats", +[](const Sim& s) { return stats_dict(s.bd->stats()); }),
                   "This rank's counters as a dict: steps, rebuilds, repartitions, halo_size, imbalance (max / mean\n"
                   "cost at the last rebuild) and seconds per part (rebuild, halo, forces, update).");
}

}  // namespace

void bind_mpi_bd(nb::module_& m) {
  SimClass cls(m, "Simulation",
               "Brownian dynamics of a config across the ranks of a communicator, step by step\n"
               "(rpyfmm::mpi::DistributedBd, docs/mpi.md): each rank holds its share of the particles.\n"
               "With free draining the positions are rpyfmm.Simulation.from_config's bit for bit.");
  cls.def("__init__", &init_simulation, nb::arg("comm"), nb::arg("config"),
          "Collective. comm: an mpi4py communicator; config: a RunConfig, a TOML file path or TOML text, the\n"
          "same on every rank. Rank r starts with the particles [r N / P, (r + 1) N / P) of the config's\n"
          "initial state, the step `mpirun rpyfmm bd` takes; a bad config on any rank raises on every rank.");
  add_steps(cls);
  add_share(cls);
  add_counters(cls);
}

}  // namespace rpyfmm::python
