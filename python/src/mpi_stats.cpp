// rpyfmm Python bindings — the MPI layer's statistics as properties (mpi_stats.hpp): dicts of this
// rank's exchanges and work, keyed by the C++ structs' field names, as rpyfmm.mpi.Simulation.stats
// (mpi_bd.cpp) and LaplaceFmm.stats() (fmm.cpp) hand out theirs. Every value is a copy taken under
// the object's lock; none is collective.
#include "mpi_stats.hpp"

#include <nanobind/stl/string.h>

#include <cstddef>
#include <cstdint>

#include "object_lock.hpp"
#include "rpyfmm/core/timer.hpp"

namespace rpyfmm::python {
namespace {

using Direct = WithComm<mpi::DistributedDirectRpy>;
using Fmm = WithComm<mpi::DistributedFmmRpy>;
using Pse = WithComm<mpi::DistributedPseRpy>;
using Laplace = WithComm<mpi::DistributedLaplaceFmm>;

nb::dict stage_dict(const StageTimes& t) {
  nb::dict d;
  for (const auto& [stage, seconds] : t) d[nb::str(stage.c_str())] = seconds;
  return d;
}

/// The fields the RPY operators' statistics share (mpi::CommunicationStats and
/// mpi::FmmRpyCommunication).
template <class Stats>
nb::dict product_dict(const Stats& s) {
  nb::dict d;
  d["set_positions_seconds"] = s.set_positions_seconds;
  d["apply_seconds"] = s.apply_seconds;
  d["apply_bytes_received"] = s.apply_bytes_received;
  d["applies_seconds"] = s.applies_seconds;
  return d;
}

nb::dict communication_dict(const mpi::CommunicationStats& s) {
  return product_dict(s);
}

nb::dict communication_dict(const mpi::FmmRpyCommunication& s) {
  nb::dict d = product_dict(s);
  d["near_set_positions_seconds"] = s.near_set_positions_seconds;
  d["near_set_positions_bytes_received"] = s.near_set_positions_bytes_received;
  d["near_apply_seconds"] = s.near_apply_seconds;
  d["near_apply_bytes_received"] = s.near_apply_bytes_received;
  d["near_sums_seconds"] = s.near_sums_seconds;
  return d;
}

nb::dict communication_dict(const mpi::FmmCommunication& s) {
  nb::dict d;
  d["plan_seconds"] = stage_dict(s.plan_seconds);
  d["plan_bytes_received"] = s.plan_bytes_received;
  d["evaluate_seconds"] = stage_dict(s.evaluate_seconds);
  d["evaluate_bytes_received"] = s.evaluate_bytes_received;
  d["compute_seconds"] = stage_dict(s.compute_seconds);
  d["halo_received"] = s.halo_received;
  d["cells_received"] = s.cells_received;
  d["nodes_received"] = s.nodes_received;
  d["halo_sent"] = s.halo_sent;
  d["cells_sent"] = s.cells_sent;
  d["nodes_sent"] = s.nodes_sent;
  d["region_boxes"] = s.region_boxes;
  d["region_neighbours"] = s.region_neighbours;
  d["region_bytes_received"] = s.region_bytes_received;
  d["region_sent_to"] = s.region_sent_to;
  return d;
}

nb::dict exchange_counts_dict(const mpi::PseExchangeCounts& s) {
  nb::dict d;
  d["wave_sent"] = s.wave_sent;
  d["wave_received"] = s.wave_received;
  d["halo_received"] = s.halo_received;
  return d;
}

nb::dict block_exchange_dict(const mpi::BlockExchangeStats& s) {
  nb::dict d;
  d["applications"] = s.applications;
  d["columns"] = s.columns;
  d["seconds"] = s.seconds;
  d["bytes_received"] = s.bytes_received;
  return d;
}

/// mpi::BlockPreconditionerStats, keyed by its fields (all zero without the block preconditioner).
nb::dict blocks_dict(const mpi::BlockPreconditionerStats& s) {
  nb::dict d;
  d["reused"] = s.reused;
  d["build_seconds"] = s.build_seconds;
  d["gather_seconds"] = s.gather_seconds;
  d["gather_bytes_received"] = s.gather_bytes_received;
  d["particles_sent"] = s.particles_sent;
  d["particles_received"] = s.particles_received;
  d["apply_g"] = block_exchange_dict(s.apply_g);
  d["apply_g_transpose"] = block_exchange_dict(s.apply_g_transpose);
  d["solve_g"] = block_exchange_dict(s.solve_g);
  return d;
}

/// The inner products and blocks of the last sampler call on this rank; None before any.
template <class Op>
nb::object inner_products(const WithComm<Op>& s) {
  const InnerProductRecord& r = s.inner_products;
  if (!r.recorded) return nb::none();
  nb::dict d;
  d["seconds"] = r.stats.seconds;
  d["exchanges"] = r.stats.exchanges;
  d["blocks"] = blocks_dict(r.stats.blocks);
  return d;
}

const char* kInnerProductsDoc =
    "This rank's inner products in the last apply_sqrt, apply_sqrt_block or apply_sqrt_rotation (None\n"
    "before any): {'seconds': its time in their MPI calls, 'exchanges': their exchanges (MPI_Allgatherv\n"
    "of chunk sums; the same on every rank), 'blocks': the block preconditioner's cost\n"
    "(mpi::BlockPreconditionerStats: 'reused', 'build_seconds', 'gather_seconds',\n"
    "'gather_bytes_received', 'particles_sent', 'particles_received', and 'apply_g',\n"
    "'apply_g_transpose', 'solve_g', each {'applications', 'columns', 'seconds', 'bytes_received'};\n"
    "all zero without it)}. Lanczos: 1 + 3 exchanges per iteration with reorthogonalization, 1 + 2\n"
    "without (docs/mpi.md, \"Brownian displacements\"). Not collective.";

/// The direct and FMM operators' every rank's counts and sampler statistics.
template <class Op>
void add_sampler_statistics(nb::class_<WithComm<Op>>& cls) {
  using Self = WithComm<Op>;
  cls.def_prop_ro("counts",
                  locked_read(
                      "counts", +[](const Self& s) { return copy_integers(s.op.counts()); }),
                  "Every rank's number of particles, in rank order (uint64; empty before set_positions).")
      .def_prop_ro("inner_products", locked_read("inner_products", &inner_products<Op>), kInnerProductsDoc);
}

}  // namespace

void add_statistics(nb::class_<Direct>& cls) {
  add_sampler_statistics(cls);
  cls.def_prop_ro("communication",
                  locked_read(
                      "communication", +[](const Direct& s) { return communication_dict(s.op.communication()); }),
                  "This rank's time in MPI calls in the last set_positions and apply, the bytes of other ranks'\n"
                  "blocks it received in the last apply, and applies_seconds, apply_seconds summed over every\n"
                  "apply since set_positions (a sampler's products included). Not collective.");
}

void add_statistics(nb::class_<Fmm>& cls) {
  add_sampler_statistics(cls);
  cls.def_prop_ro("communication",
                  locked_read(
                      "communication", +[](const Fmm& s) { return communication_dict(s.op.communication()); }),
                  "This rank's exchanges in set_positions and the products (seconds, bytes received; the\n"
                  "near_ entries the exact near field's: the radii to the owners and halo, the near velocities\n"
                  "back), reset by each set_positions. Not collective.")
      .def_prop_ro("laplace_communication",
                   locked_read(
                       "laplace_communication",
                       +[](const Fmm& s) { return communication_dict(s.op.laplace().communication()); }),
                   "The far field's DistributedLaplaceFmm.communication: its plan's and last evaluation's\n"
                   "exchanges and work on this rank. Not collective.")
      .def_prop_ro("separation",
                   locked_read(
                       "separation", +[](const Fmm& s) { return s.op.laplace().separation(); }),
                   "The far field's Laplace FMM's acceptance ratio in use.")
      .def_prop_ro("owned_size",
                   locked_read(
                       "owned_size", +[](const Fmm& s) { return s.op.laplace().owned_size(); }),
                   "The particles this rank owns in the FMM's partition (its near field's targets).")
      .def_prop_ro("halo_size",
                   locked_read(
                       "halo_size", +[](const Fmm& s) { return s.op.halo_size(); }),
                   "The halo particles of this rank's exact near field (received with their loads in each product).");
}

void add_statistics(nb::class_<Pse>& cls) {
  cls.def_prop_ro("exchange_counts",
                  locked_read(
                      "exchange_counts", +[](const Pse& s) { return exchange_counts_dict(s.op.exchange_counts()); }),
                  "This rank's exchanges in the last set_positions, in particles: positions sent to other ranks'\n"
                  "slabs (wave_sent), received for its own (wave_received), halo received. Not collective.")
      .def_prop_ro("memory_bytes",
                   locked_read(
                       "memory_bytes", +[](const Pse& s) { return s.op.memory_bytes(); }),
                   "This rank's memory as set_positions checked it against max_memory_bytes (raises before\n"
                   "set_positions; docs/mpi.md, \"Distributed PSE\").")
      .def_prop_ro("communication",
                   locked_read(
                       "communication", +[](const Pse& s) { return communication_dict(s.op.communication()); }),
                   "This rank's time in the particle exchanges (slabs and halo) of the last set_positions and\n"
                   "product (apply, sample, apply_sqrt, apply_with_noise), the bytes received from other ranks\n"
                   "in that product, and applies_seconds, summed over every product since set_positions; not\n"
                   "FFTW-MPI's transposes inside the transforms. Not collective.");
}

void add_statistics(nb::class_<Laplace>& cls) {
  cls.def_prop_ro("communication",
                  locked_read(
                      "communication", +[](const Laplace& s) { return communication_dict(s.op.communication()); }),
                  "This rank's share of the plan's and the last evaluate's work and traffic: plan_seconds,\n"
                  "evaluate_seconds and compute_seconds by stage (dicts), bytes received, and the locally\n"
                  "essential tree's halo particles, cells and nodes received and sent. Not collective.")
      .def_prop_ro("owned_size",
                   locked_read(
                       "owned_size", +[](const Laplace& s) { return s.op.owned_size(); }),
                   "The sources this rank owns after the partition.")
      .def_prop_ro("owned_target_size",
                   locked_read(
                       "owned_target_size", +[](const Laplace& s) { return s.op.owned_target_size(); }),
                   "The targets this rank owns (its owned sources when there are no targets).")
      .def_prop_ro("essential_size",
                   locked_read(
                       "essential_size", +[](const Laplace& s) { return s.op.essential_size(); }),
                   "The serial FMM's sources on this rank: owned + halo + equivalent nodes.")
      .def_prop_ro("separation",
                   locked_read(
                       "separation", +[](const Laplace& s) { return s.op.separation(); }),
                   "The acceptance ratio in use.");
}

}  // namespace rpyfmm::python
