// rpyfmm Python bindings — the space-filling-curve partition of particles held by the ranks of an
// mpi4py communicator, and the moves of per-particle data that go with it: rpyfmm.mpi.SfcPartition
// around rpyfmm::mpi::SfcPartition (docs/mpi.md, "Space-filling-curve partition" and "Python
// (mpi4py)").
//
// Conventions of mpi.cpp: the constructor and the moves are collective, argument checks are agreed
// over the ranks before the collective C++ call, the GIL is released in it, and calls on one object
// are serialized by its lock (object_lock.hpp). Every array returned is a new array that owns its
// memory.
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "mpi_common.hpp"
#include "object_lock.hpp"
#include "rpyfmm/mpi/partition.hpp"

namespace rpyfmm::python {
namespace {

constexpr const char* kWhere = "rpyfmm.mpi.SfcPartition";

/// The partition and the mpi4py communicator it works on (declared first: released after it), with
/// a view of it for the agreement on the arguments.
struct Partition {
  nb::object comm;
  mpi::Communicator world;
  std::unique_ptr<mpi::SfcPartition> part;
};

void init_partition(Partition* self, nb::object comm, ArrayArg positions, OptArrayArg weights,
                    const std::string& curve) {
  const MPI_Comm handle = comm_from(comm, kWhere);
  const mpi::Communicator world(handle);
  struct Args {
    InArray x, w;
    mpi::SfcCurve curve;
  };
  const Args a = agreed(world, [&] {
    Args r{as_input(positions, kWhere, "positions"), InArray{}, curve_from(curve, kWhere)};
    require_points(r.x, kWhere, "positions");
    if (!weights.is_none()) r.w = as_input(weights, kWhere, "weights");
    return r;
  });
  std::unique_ptr<mpi::SfcPartition> made;
  {
    nb::gil_scoped_release release;
    made = std::make_unique<mpi::SfcPartition>(handle, a.x.span(), a.w.span(), a.curve);
  }
  new (self) Partition{std::move(comm), world, std::move(made)};
}

/// Collective: the rows of `values` ((rows,) or (rows, per)) moved to the owners (forward) or back
/// to the input ranks and order; the result has the input's ndim and per.
ArrayResult move_rows(const Partition& self, ArrayArg values, bool forward) {
  const char* where = forward ? "to_owners" : "to_origin";
  const InArray v = agreed(self.world, [&] {
    InArray r = as_input(values, where, "values");
    require(r.ndim() == 1 || r.ndim() == 2, ErrorCode::invalid_input, where,
            "values has shape " + shape_string(r.shape) + ", expected (n,) or (n, per)");
    return r;
  });
  const std::size_t per = v.ndim() == 2 ? v.shape[1] : 1;
  const mpi::Column column{v.span(), per};
  std::vector<std::vector<double>> moved;
  {
    nb::gil_scoped_release release;
    moved = forward ? self.part->to_owners({&column, 1}) : self.part->to_origin({&column, 1});
  }
  const std::size_t rows = per == 0 ? 0 : moved[0].size() / per;
  if (v.ndim() == 1) return adopt_vector(std::move(moved[0]), {rows});
  return adopt_vector(std::move(moved[0]), {rows, per});
}

/// The cuts as a (P - 1, 2) array of (key, global index).
nb::object splitters(const Partition& self) {
  std::vector<std::uint64_t> flat;
  for (const mpi::SfcKey& k : self.part->splitters()) {
    flat.push_back(k.key);
    flat.push_back(k.index);
  }
  return adopt_integers(std::move(flat)).attr("reshape")(-1, 2);
}

/// One field of the owned particles' (key, global index), in their order.
template <std::uint64_t mpi::SfcKey::*Field>
nb::object owned_field(const Partition& self) {
  std::vector<std::uint64_t> v;
  for (const mpi::SfcKey& k : self.part->owned()) v.push_back(k.*Field);
  return adopt_integers(std::move(v));
}

using PartitionClass = nb::class_<Partition>;

void add_sizes(PartitionClass& cls) {
  cls.def_prop_ro(
         "comm", [](const Partition& p) { return p.comm; }, "The mpi4py communicator the partition works on.")
      .def_prop_ro(
          "curve", [](const Partition& p) { return curve_name(p.part->curve()); },
          "The space-filling curve of the order: 'morton' or 'hilbert'.")
      .def_prop_ro(
          "input_size", [](const Partition& p) { return p.part->input_size(); }, "This rank's input particles n.")
      .def_prop_ro(
          "owned_size", [](const Partition& p) { return p.part->owned_size(); },
          "The particles this rank owns after the partition m.")
      .def_prop_ro(
          "global_size", [](const Partition& p) { return p.part->global_size(); }, "The particles on all ranks N.")
      .def_prop_ro("owned_indices", &owned_field<&mpi::SfcKey::index>,
                   "The global indices (m,) of the owned particles in their order (key, then global index);\n"
                   "the global index is the place in the ranks' inputs concatenated in rank order.")
      .def_prop_ro("owned_keys", &owned_field<&mpi::SfcKey::key>,
                   "The keys (m,) of the owned particles along the curve, in the same order (non-decreasing).")
      .def_prop_ro("splitters", &splitters,
                   "The P - 1 cuts as a (P - 1, 2) array of (key, global index): rank r owns the particles with\n"
                   "splitters[r - 1] <= (key, index) < splitters[r].")
      .def_prop_ro(
          "owned_counts", [](const Partition& p) { return copy_integers(p.part->owned_counts()); },
          "Every rank's number of owned particles (P,).")
      .def_prop_ro(
          "owned_weights",
          [](const Partition& p) { return adopt_vector(p.part->owned_weights(), {p.part->owned_counts().size()}); },
          "Every rank's owned weight (P,), the weights as the partition balanced them.")
      .def_prop_ro(
          "imbalance", [](const Partition& p) { return p.part->imbalance(); },
          "max over the ranks of the owned weight / its mean (1 for no weight at all).")
      .def_prop_ro(
          "cube",
          [](const Partition& p) {
            const mpi::KeyCube& c = p.part->cube();
            return nb::make_tuple(nb::make_tuple(c.origin[0], c.origin[1], c.origin[2]), 2.0 * c.half_side);
          },
          "(origin (x, y, z), side) of the cube in which the Morton keys are taken.");
}

}  // namespace

mpi::SfcCurve curve_from(const std::string& name, const std::string& where) {
  if (name == "morton") return mpi::SfcCurve::morton;
  if (name == "hilbert") return mpi::SfcCurve::hilbert;
  fail(ErrorCode::invalid_argument, where, "curve must be 'morton' or 'hilbert', got '" + name + "'");
}

const char* curve_name(mpi::SfcCurve curve) {
  return curve == mpi::SfcCurve::hilbert ? "hilbert" : "morton";
}

void bind_mpi_partition(nb::module_& m) {
  PartitionClass cls(m, "SfcPartition",
                     "Weighted space-filling-curve partition of the particles the ranks hold\n"
                     "(rpyfmm::mpi::SfcPartition, docs/mpi.md): the global order by (key, global index) cut into P\n"
                     "ranges of balanced weight, and the moves of per-particle data to the owners and back.");
  cls.def("__init__", &init_partition, nb::arg("comm"), nb::arg("positions"), nb::arg("weights") = nb::none(),
          nb::arg("curve") = "morton",
          "Collective. comm: an mpi4py communicator; positions: this rank's particles, (n, 3) or (3n,), n >= 0;\n"
          "weights: None (1 each) or n finite weights >= 0; curve: 'morton' or 'hilbert', the same on every\n"
          "rank. A bad input on any rank raises on every rank.");
  add_sizes(cls);
  cls.def(
         "to_owners",
         locked(
             "SfcPartition.to_owners", +[](const Partition& p, ArrayArg values) { return move_rows(p, values, true); }),
         nb::arg("values"),
         "Collective. This rank's input rows ((n,) or (n, per), float64, the same per on every rank) moved to\n"
         "the owners: returns (m,) or (m, per) in the owned order, bit for bit.")
      .def("to_origin",
           locked(
               "SfcPartition.to_origin",
               +[](const Partition& p, ArrayArg values) { return move_rows(p, values, false); }),
           nb::arg("values"),
           "Collective. The inverse of to_owners: the owned rows ((m,) or (m, per)) back to the input ranks and\n"
           "order, (n,) or (n, per), bit for bit.");
}

}  // namespace rpyfmm::python
