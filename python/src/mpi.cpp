// rpyfmm Python bindings — the MPI layer's distributed operators (rpyfmm::mpi, docs/mpi.md,
// "Python (mpi4py)") as the submodule rpyfmm._rpyfmm.mpi, wrapped by python/rpyfmm/mpi.py:
// DistributedDirectRpy, DistributedFmmRpy (with the samplers of mpi::sqrt_apply),
// DistributedPseRpy (with its split sampler), DistributedLaplaceFmm, and normal_noise for a rank's
// share (mpi::fill_normal), the whole BD runs; rpyfmm.mpi.Simulation (BD step by step) is bound in
// mpi_bd.cpp, rpyfmm.mpi.SfcPartition in mpi_partition.cpp. Compiled only where the MPI layer is built.
//
// Communicator: the constructors take an mpi4py communicator and convert it through its Fortran
// handle, mpi4py's comm.py2f() then MPI_Comm_f2c here, which needs neither mpi4py's C headers at
// build time nor mpi4py's C API at run time. Each object keeps a reference to the mpi4py communicator (its
// `comm`), so that the communicator outlives the object (communicator.hpp).
//
// Collective errors: every call is collective. The arguments are checked here first (shapes,
// conversions) and the ranks agree on the outcome (Communicator::agree, one allreduce) before the
// collective C++ call, so that a bad argument on one rank raises the same exception on every rank
// instead of leaving the others waiting; the C++ call itself fails collectively (NaN, sizes).
//
// Arrays and locks follow mobility.cpp: each rank's arrays are (n, 3) or (3n,) views (n may be 0),
// results come back in the input's shape, the GIL is released during the C++ call, and calls on one
// object are serialized by its lock (object_lock.hpp).
#include <mpi.h>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <type_traits>
#include <utility>

#include "common.hpp"
#include "mpi_common.hpp"
#include "mpi_stats.hpp"
#include "object_lock.hpp"
#include "rpyfmm/bd/run.hpp"
#include "rpyfmm/mpi/bd_stepper.hpp"
#include "rpyfmm/mpi/direct_operator.hpp"
#include "rpyfmm/mpi/fmm_rpy.hpp"
#include "rpyfmm/mpi/laplace_fmm.hpp"
#include "rpyfmm/mpi/pse_operator.hpp"
#include "rpyfmm/mpi/sqrt.hpp"
#include "run_arguments.hpp"

namespace rpyfmm::python {

MPI_Comm comm_from(nb::handle comm, const char* where) {
  if (!nb::hasattr(comm, "py2f")) {
    fail(ErrorCode::invalid_argument, where,
         "comm must be an mpi4py communicator (mpi4py.MPI.Comm), got " +
             std::string(nb::type_name(comm.type()).c_str()));
  }
  const auto handle = nb::cast<long long>(comm.attr("py2f")());
  return MPI_Comm_f2c(static_cast<MPI_Fint>(handle));
}

namespace {

using Direct = WithComm<mpi::DistributedDirectRpy>;
using Fmm = WithComm<mpi::DistributedFmmRpy>;
using Pse = WithComm<mpi::DistributedPseRpy>;
using Laplace = WithComm<mpi::DistributedLaplaceFmm>;

/// A product's arrays on this rank: its input (n, 3) or (3n,), and the output in the same shape.
struct InOut {
  InArray in;
  OutArray out;
};

/// Checks and converts a product's arrays on this rank (not collective).
InOut points_in_out(const std::string& where, ArrayArg in, const char* name, OutArg out) {
  InArray a = as_input(in, where, name);
  require_points(a, where, name);
  OutArray u = make_output(out, a.shape, where, &a);
  return InOut{std::move(a), std::move(u)};
}

/// points_in_out, agreed over the ranks.
InOut agreed_in_out(const mpi::Communicator& comm, const std::string& where, ArrayArg in, const char* name,
                    OutArg out) {
  return agreed(comm, [&] { return points_in_out(where, in, name, out); });
}

template <class Op>
void set_positions(WithComm<Op>& self, ArrayArg positions, RadiusArg radius) {
  const std::string where = "set_positions";
  struct Args {
    InArray x;
    Radii r;
  };
  const Args a = agreed(self.op.communicator(), [&] {
    InArray x = as_input(positions, where, "positions");
    require_points(x, where, "positions");
    return Args{std::move(x), radii_from(radius, where)};
  });
  nb::gil_scoped_release release;
  if (a.r.scalar) {
    self.op.set_positions(a.x.span(), a.r.values[0]);
  } else {
    self.op.set_positions(a.x.span(), a.r.values);
  }
}

template <class Op>
ArrayResult apply(const WithComm<Op>& self, ArrayArg forces, OutArg out) {
  InOut a = agreed_in_out(self.op.communicator(), "apply", forces, "forces", out);
  {
    nb::gil_scoped_release release;
    self.op.apply(a.in.span(), a.out.span());
  }
  return ArrayResult{a.out.object};
}

/// The arrays of a sample on this rank: z, w in z's shape, and the number of columns: one for
/// apply_sqrt ((n, 3) or (3n,)), nrhs for apply_sqrt_block ((nrhs, n, 3) or (nrhs, 3n), as the
/// serial MobilityOperator.apply_sqrt_block). Not collective.
struct SampleArrays {
  InOut arrays;
  std::size_t nrhs = 1;
};

template <bool Block>
SampleArrays sample_arrays(const std::string& where, ArrayArg z, OutArg out) {
  if constexpr (!Block) return SampleArrays{points_in_out(where, z, "z", out), 1};
  InArray a = as_input(z, where, "z");
  const std::size_t nrhs = block_count(a, where, "z");
  OutArray w = make_output(out, a.shape, where, &a);
  return SampleArrays{InOut{std::move(a), std::move(w)}, nrhs};
}

/// w = M^{1/2} z on this rank's share: mpi::sqrt_apply (direct, fmm; with Block, its variant for
/// several right-hand sides) or the PSE's split sampler (one column).
template <class Op, bool Block = false>
ArrayAndReport<rpy::SqrtReport> apply_sqrt(const WithComm<Op>& self, ArrayArg z, OutArg out, const std::string& method,
                                           double tolerance, int max_iterations, bool reorthogonalize,
                                           bool throw_if_not_converged, double lambda_min, double lambda_max,
                                           int bound_estimate_iterations, const std::string& preconditioner,
                                           int preconditioner_block) {
  const std::string where = Block ? "apply_sqrt_block" : "apply_sqrt";
  struct Args {
    rpy::SqrtOptions options;
    SampleArrays sample;
  };
  Args a = agreed(self.op.communicator(), [&] {
    return Args{sqrt_options(method, tolerance, max_iterations, reorthogonalize, throw_if_not_converged, lambda_min,
                             lambda_max, bound_estimate_iterations, preconditioner, preconditioner_block),
                sample_arrays<Block>(where, z, out)};
  });
  InOut& io = a.sample.arrays;
  rpy::SqrtReport report;
  {
    nb::gil_scoped_release release;
    if constexpr (std::is_same_v<Op, mpi::DistributedPseRpy>) {
      static_assert(!Block, "the PSE's split sampler takes one column");
      report = self.op.apply_sqrt(io.in.span(), io.out.span(), a.options);
    } else {
      // One column is the call with nrhs = 1 (the same iteration and bits, rpyfmm/mpi/sqrt.hpp),
      // which also counts the inner products' exchanges.
      mpi::InnerProductStats stats;
      report = mpi::sqrt_apply(self.op, io.in.span(), io.out.span(), a.sample.nrhs, a.options, &stats);
      self.inner_products = {true, stats};
    }
  }
  return array_and_report(io.out.object, report);
}

template <class Op>
using Class = nb::class_<WithComm<Op>>;

/// apply_sqrt (Block = false) or apply_sqrt_block (Block = true) with their keywords (the same for
/// both, as the serial MobilityOperator's).
template <class Op, bool Block>
void add_apply_sqrt(Class<Op>& cls, const char* name, const char* doc) {
  cls.def(name, locked(name, &apply_sqrt<Op, Block>), nb::arg("z"), nb::arg("out") = nb::none(), nb::kw_only(),
          nb::arg("method") = "auto", nb::arg("tolerance") = rpy::SqrtOptions{}.tolerance,
          nb::arg("max_iterations") = 0, nb::arg("reorthogonalize") = true, nb::arg("throw_if_not_converged") = true,
          nb::arg("lambda_min") = 0.0, nb::arg("lambda_max") = 0.0, nb::arg("bound_estimate_iterations") = 30,
          nb::arg("preconditioner") = "none", nb::arg("preconditioner_block") = 0, doc);
}

const char* kApplyDoc =
    "Collective. U = M F for this rank's particles: forces (n, 3) or (3n,); returns the velocities in\n"
    "the same shape (float64); `out` (writable float64, C-contiguous) is written in place and returned.";

/// What every distributed operator offers: its communicator, sizes, set_positions, apply (U = M F;
/// unless the class binds its own, with_apply = false), apply_sqrt.
template <class Op>
void add_common(Class<Op>& cls, const char* sqrt_doc, bool with_apply = true) {
  using Self = WithComm<Op>;
  cls.def_prop_ro(
         "comm", [](const Self& s) { return s.comm; }, "The mpi4py communicator the operator works on.")
      .def_prop_ro(
          "name", [](const Self& s) { return s.op.name(); }, "Solver name: 'direct-mpi', 'fmm-mpi', 'pse-mpi'.")
      .def_prop_ro(
          "viscosity", [](const Self& s) { return s.op.viscosity(); }, "Solvent viscosity eta.")
      .def_prop_ro("local_size",
                   locked_read(
                       "local_size", +[](const Self& s) { return s.op.local_size(); }),
                   "This rank's number of particles n (0 before set_positions).")
      .def_prop_ro("global_size",
                   locked_read(
                       "global_size", +[](const Self& s) { return s.op.global_size(); }),
                   "The number of particles on all ranks together N (0 before set_positions).")
      .def_prop_ro("offset",
                   locked_read(
                       "offset", +[](const Self& s) { return s.op.offset(); }),
                   "The global index of this rank's first particle (the ranks' shares in rank order).");
  cls.def("set_positions", locked("set_positions", &set_positions<Op>), nb::arg("positions"), nb::arg("radius"),
          "Collective. This rank's positions ((n, 3) or (3n,), n >= 0, length units) and radius: one number\n"
          "for them or an array of n radii. The global set is the ranks' shares concatenated in rank order.");
  if (with_apply) {
    cls.def("apply", locked("apply", &apply<Op>), nb::arg("forces"), nb::arg("out") = nb::none(), kApplyDoc);
  }
  add_apply_sqrt<Op, false>(cls, "apply_sqrt", sqrt_doc);
}

const char* kKrylovSqrtDoc =
    "Collective. w = M^{1/2} z on this rank's share of z ((n, 3) or (3n,)); returns (w, SqrtReport).\n"
    "mpi::sqrt_apply: method 'auto'/'lanczos' or 'chebyshev' (others raise NotSupportedError), keywords\n"
    "as MobilityOperator.apply_sqrt; inner products are summed over all ranks (docs/mpi.md).";

void init_direct(Direct* self, nb::object comm, double viscosity) {
  new (self) Direct{comm, mpi::DistributedDirectRpy(comm_from(comm, "DistributedDirectRpy"), viscosity)};
}

/// U = M F; with torques, (U, W) = M (F, T) (the operator's apply with rotation), spelled as
/// MobilityOperator.apply (mobility.cpp); the arrays' checks agreed over the ranks.
template <class Op>
nb::object apply_with_rotation(const WithComm<Op>& self, ArrayArg forces, OptArrayArg torques, OutArg out) {
  if (torques.is_none()) return apply(self, forces, out).o;
  const RotationArrays a =
      agreed(self.op.communicator(), [&] { return rotation_arrays(forces, torques, out, "apply"); });
  {
    nb::gil_scoped_release release;
    self.op.apply(a.f.span(), a.t.span(), a.u.span(), a.w.span());
  }
  return nb::make_tuple(a.u.object, a.w.object);
}

const std::string kRotationApplyDoc =
    std::string(kApplyDoc) +
    "\nWith torques (same shape as forces): returns (U, W) = M (F, T), the velocities and angular\n"
    "velocities of the grand mobility with rotation; `out` is not supported with torques.";

/// [w_t; w_r] = B [z_t; z_r] with B B^T = the grand mobility, on this rank's share:
/// mpi::sqrt_apply_rotation (direct, fmm) or the PSE's split sampler with rotation; the arguments'
/// checks agreed over the ranks.
template <class Op>
RotationSample apply_sqrt_rotation(const WithComm<Op>& self, ArrayArg z_translation, ArrayArg z_rotation,
                                   const std::string& method, double tolerance, int max_iterations,
                                   bool reorthogonalize, bool throw_if_not_converged, double lambda_min,
                                   double lambda_max, int bound_estimate_iterations, const std::string& preconditioner,
                                   int preconditioner_block) {
  const std::string where = "apply_sqrt_rotation";
  struct Args {
    rpy::SqrtOptions options;
    RotationArrays arrays;
  };
  const Args a = agreed(self.op.communicator(), [&] {
    return Args{sqrt_options(method, tolerance, max_iterations, reorthogonalize, throw_if_not_converged, lambda_min,
                             lambda_max, bound_estimate_iterations, preconditioner, preconditioner_block),
                paired_arrays(z_translation, z_rotation, where, "z_translation", "z_rotation")};
  });
  const RotationArrays& r = a.arrays;
  rpy::SqrtReport report;
  {
    nb::gil_scoped_release release;
    if constexpr (std::is_same_v<Op, mpi::DistributedPseRpy>) {
      report = self.op.apply_sqrt_rotation(r.f.span(), r.t.span(), r.u.span(), r.w.span(), a.options);
    } else {
      mpi::InnerProductStats stats;
      report = mpi::sqrt_apply_rotation(self.op, r.f.span(), r.t.span(), r.u.span(), r.w.span(), a.options, stats);
      self.inner_products = {true, stats};
    }
  }
  return rotation_sample(r, report);
}

const char* kSqrtRotationDoc =
    "Collective. Brownian displacements and rotations of this rank's particles: (w_t, w_r) = B (z_t, z_r)\n"
    "with B B^T = the grand mobility; z_translation, z_rotation: this rank's share, (n, 3) or (3n,), the\n"
    "same shape. Returns (w_t, w_r, SqrtReport). Keywords and scaling as MobilityOperator.apply_sqrt_rotation;\n"
    "the methods as apply_sqrt offers them on this operator (docs/mpi.md).";

/// apply with optional torques and supports_rotation, for the operators with rotation.
template <class Op>
void add_rotation_apply(Class<Op>& cls) {
  cls.def("apply", locked("apply", &apply_with_rotation<Op>), nb::arg("forces"), nb::arg("torques") = nb::none(),
          nb::arg("out") = nb::none(), kRotationApplyDoc.c_str())
      .def_prop_ro(
          "supports_rotation", [](const WithComm<Op>& s) { return s.op.supports_rotation(); },
          "True: apply accepts torques and apply_sqrt_rotation samples (the grand mobility with rotation).");
  cls.def("apply_sqrt_rotation", locked("apply_sqrt_rotation", &apply_sqrt_rotation<Op>), nb::arg("z_translation"),
          nb::arg("z_rotation"), nb::kw_only(), nb::arg("method") = "auto",
          nb::arg("tolerance") = rpy::SqrtOptions{}.tolerance, nb::arg("max_iterations") = 0,
          nb::arg("reorthogonalize") = true, nb::arg("throw_if_not_converged") = true, nb::arg("lambda_min") = 0.0,
          nb::arg("lambda_max") = 0.0, nb::arg("bound_estimate_iterations") = 30, nb::arg("preconditioner") = "none",
          nb::arg("preconditioner_block") = 0, kSqrtRotationDoc);
}

/// U_r = M F_r for a block of right-hand sides on this rank's share ((nrhs, n, 3) or (nrhs, 3n)), one
/// pass for all of them (the operator's apply_block); the arrays' checks agreed over the ranks.
template <class Op>
ArrayResult apply_block(const WithComm<Op>& self, ArrayArg forces, OutArg out) {
  const std::string where = "apply_block";
  struct Args {
    InArray f;
    OutArray u;
    std::size_t nrhs = 0;
  };
  Args a = agreed(self.op.communicator(), [&] {
    InArray f = as_input(forces, where, "forces");
    const std::size_t nrhs = block_count(f, where, "forces");
    OutArray u = make_output(out, f.shape, where, &f);
    return Args{std::move(f), std::move(u), nrhs};
  });
  {
    nb::gil_scoped_release release;
    self.op.apply_block(a.f.span(), a.u.span(), a.nrhs);
  }
  return ArrayResult{a.u.object};
}

const char* kApplyBlockDoc =
    "Collective. U_r = M F_r for nrhs right-hand sides on this rank's particles: forces (nrhs, n, 3) or\n"
    "(nrhs, 3n), every rank the same nrhs; returns the velocities in the same shape. One pass over the\n"
    "ranks for all of them; each right-hand side equals apply of it alone bit for bit (docs/mpi.md).";

const char* kSqrtBlockDoc =
    "Collective. w_r = M^{1/2} z_r for nrhs right-hand sides on this rank's share: z (nrhs, n, 3) or\n"
    "(nrhs, 3n), every rank the same nrhs, as MobilityOperator.apply_sqrt_block; returns (w in z's shape,\n"
    "SqrtReport). mpi::sqrt_apply with several right-hand sides: one apply_block per iteration for the\n"
    "columns still iterating; each column equals apply_sqrt of it alone bit for bit; the report's\n"
    "iterations and error_estimate are the largest over the columns (docs/mpi.md).";

/// apply_block, for the operators that offer several right-hand sides per pass.
template <class Op>
void add_apply_block(Class<Op>& cls) {
  cls.def("apply_block", locked("apply_block", &apply_block<Op>), nb::arg("forces"), nb::arg("out") = nb::none(),
          kApplyBlockDoc);
  add_apply_sqrt<Op, true>(cls, "apply_sqrt_block", kSqrtBlockDoc);
}

void bind_distributed_direct(nb::module_& m) {
  Class<mpi::DistributedDirectRpy> cls(m, "DistributedDirectRpy",
                                       "Exact O(N^2) RPY mobility on particles distributed over the ranks (free "
                                       "space); equal bit for bit\nto DirectRpy on the ranks' shares concatenated in "
                                       "rank order (with torques too).");
  cls.def("__init__", &init_direct, nb::arg("comm"), nb::arg("viscosity") = 1.0,
          "Collective. comm: an mpi4py communicator; viscosity: eta > 0.");
  add_common(cls, kKrylovSqrtDoc, false);
  add_rotation_apply(cls);
  add_apply_block(cls);
  add_statistics(cls);
}

/// The curve named `name`, agreed over the ranks of `comm` (a bad name on any rank raises on all).
mpi::SfcCurve agreed_curve(MPI_Comm comm, const std::string& name, const char* where) {
  return agreed(mpi::Communicator(comm), [&] { return curve_from(name, where); });
}

void init_fmm(Fmm* self, nb::object comm, double viscosity, double tolerance, int leaf_capacity, bool overlap_exchange,
              double separation, std::size_t cell_capacity, const std::string& curve) {
  const MPI_Comm handle = comm_from(comm, "DistributedFmmRpy");
  mpi::DistributedFmmRpyOptions o;
  o.curve = agreed_curve(handle, curve, "DistributedFmmRpy");
  o.tolerance = tolerance;
  o.leaf_capacity = leaf_capacity;
  o.overlap_exchange = overlap_exchange;
  o.separation = separation;
  o.cell_capacity = cell_capacity;
  new (self) Fmm{comm, mpi::DistributedFmmRpy(handle, viscosity, o)};
}

void bind_distributed_fmm(nb::module_& m) {
  Class<mpi::DistributedFmmRpy> cls(
      m, "DistributedFmmRpy",
      "Free-space RPY mobility in O(N) by the distributed Laplace FMM plus the exact "
      "near field; relative l2\nerror of U (and of W with torques) over all particles at most the tolerance.");
  cls.def("__init__", &init_fmm, nb::arg("comm"), nb::arg("viscosity") = 1.0, nb::arg("tolerance") = 1e-6,
          nb::arg("leaf_capacity") = 0, nb::arg("overlap_exchange") = false, nb::arg("separation") = 0.0,
          nb::arg("cell_capacity") = 0, nb::arg("curve") = "morton",
          "Collective. comm: an mpi4py communicator; tolerance: relative l2 error of U in [1e-12, 1e-1];\n"
          "leaf_capacity: 0 = automatic; overlap_exchange: the Laplace FMM's serial FMM split to run during\n"
          "the exchanges; separation (0 or in [1, 100]) and cell_capacity (0 = automatic): the Laplace FMM's\n"
          "exchange of the essential tree; curve: 'morton' or 'hilbert', the partition's space-filling curve\n"
          "(docs/mpi.md). Every rank must pass the same values.")
      .def_prop_ro(
          "tolerance", [](const Fmm& s) { return s.op.options().tolerance; },
          "Requested relative l2 error of U (and of W with torques).")
      .def_prop_ro(
          "curve", [](const Fmm& s) { return curve_name(s.op.options().curve); },
          "The partition's space-filling curve: 'morton' or 'hilbert'.");
  add_common(cls, kKrylovSqrtDoc, false);
  add_rotation_apply(cls);
  add_apply_block(cls);
  add_statistics(cls);
}

void init_pse(Pse* self, nb::object comm, BoxArg box, double viscosity, double tolerance, double xi, double r_cut,
              double window_eta, int fft_threads, std::size_t max_memory_bytes, bool fft_measure,
              bool real_space_cache) {
  const char* where = "DistributedPseRpy";
  const rpy::pse::PseOptions o = pse_options(where, tolerance, xi, r_cut, window_eta, fft_threads, max_memory_bytes,
                                             fft_measure, "double", real_space_cache);
  new (self) Pse{comm, mpi::DistributedPseRpy(comm_from(comm, where), geometry_from(box, where), viscosity, o)};
}

/// The PSE's split sampler keyed by (seed, step): w (n, 3) on this rank.
ArrayAndReport<rpy::SqrtReport> pse_sample(const Pse& self, std::uint64_t seed, std::uint64_t step, OutArg out) {
  OutArray w = agreed(self.op.communicator(), [&] { return make_output(out, {self.op.local_size(), 3}, "sample"); });
  rpy::SqrtReport report;
  {
    nb::gil_scoped_release release;
    report = self.op.sample(seed, step, w.span());
  }
  return array_and_report(w.object, report);
}

ArrayAndReport<rpy::SqrtReport> pse_apply_with_noise(const Pse& self, ArrayArg forces, double noise_scale,
                                                     std::uint64_t seed, std::uint64_t step, OutArg out) {
  InOut a = agreed_in_out(self.op.communicator(), "apply_with_noise", forces, "forces", out);
  rpy::SqrtReport report;
  {
    nb::gil_scoped_release release;
    report = self.op.apply_with_noise(a.in.span(), noise_scale, seed, step, a.out.span());
  }
  return array_and_report(a.out.object, report);
}

void bind_distributed_pse(nb::module_& m) {
  Class<mpi::DistributedPseRpy> cls(
      m, "DistributedPseRpy",
      "Periodic RPY mobility by Positively Split Ewald on particles distributed over the ranks, equal radii;\n"
      "equal to PseRpy (double wave grids) on the ranks' shares concatenated in rank order to round-off\n"
      "(with torques too).");
  cls.def("__init__", &init_pse, nb::arg("comm"), nb::arg("box"), nb::arg("viscosity") = 1.0,
          nb::arg("tolerance") = 1e-3, nb::arg("xi") = 0.0, nb::arg("r_cut") = 0.0, nb::arg("window_eta") = 0.0,
          nb::arg("fft_threads") = 0, nb::arg("max_memory_bytes") = std::size_t{16} << 30,
          nb::arg("fft_measure") = false, nb::arg("real_space_cache") = true,
          "Collective. comm: an mpi4py communicator; the other keywords as PseRpy's (the wave-space grids\n"
          "are double precision; max_memory_bytes bounds each rank's slab and windows, docs/mpi.md). Every\n"
          "rank must pass the same values.")
      .def_prop_ro("parameters",
                   locked_read(
                       "parameters", +[](const Pse& s) { return pse_parameters(s.op.parameters()); }),
                   "The parameters PseRpy chooses for the whole set (raises before set_positions).")
      .def("sample", locked("sample", &pse_sample), nb::arg("seed"), nb::arg("step") = 0, nb::arg("out") = nb::none(),
           "Collective. w = M^{1/2} z by PseRpy.sample's split sampler with noise keyed by (seed, step) and\n"
           "each particle's global index; returns (w (n, 3), SqrtReport).")
      .def("apply_with_noise", locked("apply_with_noise", &pse_apply_with_noise), nb::arg("forces"),
           nb::arg("noise_scale"), nb::arg("seed"), nb::arg("step") = 0, nb::arg("out") = nb::none(),
           "Collective. U = M F + noise_scale M^{1/2} z in one pass, z as sample(seed, step) draws it.");
  add_common(cls,
             "Collective. PseRpy.apply_sqrt's split sampler on this rank's share of z ((n, 3) or (3n,)): method\n"
             "'auto' or 'split' only (others raise NotSupportedError); returns (w, SqrtReport).",
             false);
  add_rotation_apply(cls);
  add_statistics(cls);
}

void init_laplace(Laplace* self, nb::object comm, double tolerance, int leaf_capacity, int order, double separation,
                  std::size_t cell_capacity, bool overlap_exchange, const std::string& curve) {
  const MPI_Comm handle = comm_from(comm, "DistributedLaplaceFmm");
  mpi::DistributedFmmOptions o;
  o.curve = agreed_curve(handle, curve, "DistributedLaplaceFmm");
  o.fmm.tolerance = tolerance;
  o.fmm.leaf_capacity = leaf_capacity;
  o.fmm.order = order;
  o.separation = separation;
  o.cell_capacity = cell_capacity;
  o.overlap_exchange = overlap_exchange;
  new (self) Laplace{comm, mpi::DistributedLaplaceFmm(handle, o)};
}

/// Sources, and targets where given (None: none on this rank), as LaplaceFmm.set_points.
/// Sources, targets where given (None: none on this rank) and partition weights of the sources
/// where given (None: 1 each), as LaplaceFmm.set_points; the weights' size and values are the C++
/// call's collective checks.
void set_points(Laplace& self, ArrayArg sources, OptArrayArg targets, OptArrayArg weights) {
  const std::string where = "set_points";
  struct Args {
    InArray s, t, w;
  };
  const Args a = agreed(self.op.communicator(), [&] {
    Args r{as_input(sources, where, "sources"), InArray{}, InArray{}};
    require_points(r.s, where, "sources");
    if (!targets.is_none()) {
      r.t = as_input(targets, where, "targets");
      require_points(r.t, where, "targets");
    }
    if (!weights.is_none()) {
      r.w = as_input(weights, where, "weights");
      require(r.w.ndim() == 1, ErrorCode::invalid_input, where,
              "weights has shape " + shape_string(r.w.shape) + ", expected (n,)");
    }
    return r;
  });
  nb::gil_scoped_release release;
  self.op.set_points(a.s.span(), a.t.span(), a.w.span());
}

/// Collective: the partition weights of this rank's sources measured in the last evaluate.
ArrayResult measured_weights(const Laplace& self) {
  std::vector<double> w;
  {
    nb::gil_scoped_release release;
    w = self.op.measured_weights();
  }
  const std::size_t n = w.size();
  return adopt_vector(std::move(w), {n});
}

ArrayResult evaluate(const Laplace& self, ArrayArg charges, nb::handle outputs, OutArg out) {
  const std::string where = "evaluate";
  struct Args {
    unsigned mask;
    std::size_t nd;
    InArray q;
    OutArray r;
  };
  Args a = agreed(self.op.communicator(), [&] {
    const unsigned mask = outputs_from(outputs, where);
    InArray q = as_input(charges, where, "charges");
    const std::size_t nd = densities(q, where);
    OutArray r = make_output(out, result_shape(q, self.op.local_target_size()), where, &q);
    return Args{mask, nd, std::move(q), std::move(r)};
  });
  {
    nb::gil_scoped_release release;
    self.op.evaluate(a.q.span(), a.nd, a.mask, a.r.span());
  }
  return ArrayResult{a.r.object};
}

void bind_distributed_laplace(nb::module_& m) {
  Class<mpi::DistributedLaplaceFmm> cls(
      m, "DistributedLaplaceFmm",
      "Laplace FMM phi(x) = sum_j q_j / |x - y_j| (no 1/(4 pi)) on sources distributed over the ranks, at\n"
      "each rank's own sources or targets; the accuracy contract of LaplaceFmm (docs/theory/fmm.md, Sec. 7).");
  cls.def("__init__", &init_laplace, nb::arg("comm"), nb::arg("tolerance") = 1e-6, nb::arg("leaf_capacity") = 0,
          nb::arg("order") = 0, nb::arg("separation") = 0.0, nb::arg("cell_capacity") = 0,
          nb::arg("overlap_exchange") = false, nb::arg("curve") = "morton",
          "Collective. comm: an mpi4py communicator; tolerance, leaf_capacity, order: each rank's serial\n"
          "LaplaceFmm; separation (0 or in [1, 100]) and cell_capacity: the exchange of the essential tree\n"
          "(0 = automatic); overlap_exchange: the serial FMM split to run during the exchanges; curve:\n"
          "'morton' or 'hilbert', the partition's space-filling curve (docs/mpi.md). Every rank must pass the\n"
          "same values.")
      .def_prop_ro(
          "comm", [](const Laplace& s) { return s.comm; }, "The mpi4py communicator the plan works on.")
      .def_prop_ro(
          "tolerance", [](const Laplace& s) { return s.op.options().fmm.tolerance; },
          "Requested accuracy (LaplaceFmm's).")
      .def_prop_ro(
          "curve", [](const Laplace& s) { return curve_name(s.op.options().curve); },
          "The partition's space-filling curve: 'morton' or 'hilbert'.")
      .def_prop_ro("local_size",
                   locked_read(
                       "local_size", +[](const Laplace& s) { return s.op.local_size(); }),
                   "This rank's sources in the last set_points (0 before).")
      .def_prop_ro("global_size",
                   locked_read(
                       "global_size", +[](const Laplace& s) { return s.op.global_size(); }),
                   "The sources on all ranks together.")
      .def_prop_ro("local_target_size",
                   locked_read(
                       "local_target_size", +[](const Laplace& s) { return s.op.local_target_size(); }),
                   "This rank's rows of results: its targets, or its sources when no rank passed targets.")
      .def("set_points", locked("set_points", &set_points), nb::arg("sources"), nb::arg("targets") = nb::none(),
           nb::arg("weights") = nb::none(),
           "Collective. This rank's sources ((n, 3) or (3n,), n >= 0) and targets ((t, 3), or None). When no\n"
           "rank passes targets, results are at each rank's sources (self pair skipped); when any rank\n"
           "does, at each rank's targets (none on a rank passing None). weights: (n,) finite, >= 0\n"
           "partition weights of this rank's sources (None: 1 each), e.g. measured_weights().")
      .def("measured_weights", locked("measured_weights", &measured_weights),
           "Collective. (n,) partition weights of this rank's sources from the measured cost of the last\n"
           "evaluate (each source's share of its leaf's seconds; a measurement, different from run to run):\n"
           "passed to set_points with the same sources they balance the plan by the work. Results at the\n"
           "sources only (with targets every rank raises NotSupportedError).")
      .def("evaluate", locked("evaluate", &evaluate), nb::arg("charges"), nb::arg("outputs") = "all",
           nb::arg("out") = nb::none(),
           "Collective. charges: (n,) or (nd, n) for this rank's sources (nd and outputs the same on every\n"
           "rank); outputs as LaplaceFmm.evaluate. Returns (t, 10) or (nd, t, 10) at this rank's rows, the\n"
           "sums over every rank's sources.");
  add_statistics(cls);
}

/// Not collective: this rank's share of the serial noise, rows [offset, offset + n) of normal_noise.
ArrayResult normal_noise(std::size_t n, std::size_t offset, std::uint64_t seed, std::uint64_t step,
                         std::uint32_t stream, OutArg out) {
  OutArray z = make_output(out, {n, 3}, "normal_noise");
  {
    nb::gil_scoped_release release;
    mpi::fill_normal(z.span(), offset, seed, step, stream);
  }
  return ArrayResult{z.object};
}

// A whole BD run across the ranks of `comm` (rpyfmm/mpi/bd_stepper.hpp): every rank steps its
// share, rank 0 writes the files. The config is read on every rank, its failures agreed.
nb::dict run_across_ranks(nb::handle comm, const char* where,
                          const std::function<bd::RunSummary(const bd::RunOptions&)>& run,
                          std::optional<std::uint64_t> steps, std::optional<std::string> out_dir, bool progress) {
  const MPI_Comm handle = comm_from(comm, where);
  const mpi::Communicator world(handle);
  const bd::RunOptions options = mpi::across_ranks(handle, run_options(steps, out_dir, progress));
  bd::RunSummary s;
  {
    nb::gil_scoped_release release;
    s = run(options);
  }
  nb::dict d = summary_dict(s);
  d["ranks"] = world.size();
  return d;
}

void bind_runs(nb::module_& m) {
  m.def(
      "run_bd",
      [](nb::object comm, nb::handle config, std::optional<std::uint64_t> steps, std::optional<std::string> out_dir,
         bool progress) {
        const mpi::Communicator world(comm_from(comm, "rpyfmm.mpi.run_bd"));
        const bd::RunConfig parsed = agreed(world, [&] { return config_from(config); });
        return run_across_ranks(
            comm, "rpyfmm.mpi.run_bd", [&](const bd::RunOptions& o) { return bd::run_bd(parsed, o); }, steps, out_dir,
            progress);
      },
      nb::arg("comm"), nb::arg("config"), nb::arg("steps") = nb::none(), nb::arg("out_dir") = nb::none(),
      nb::arg("progress") = false,
      "Collective. rpyfmm.run_bd across the ranks of comm (`mpirun rpyfmm bd`): DistributedBd steps each\n"
      "rank's share, rank 0 writes the trajectory, log and checkpoint. Returns the summary with 'ranks'.");
  m.def(
      "restart_bd",
      [](nb::object comm, const std::filesystem::path& checkpoint, std::optional<std::uint64_t> steps,
         std::optional<std::string> out_dir, bool progress) {
        return run_across_ranks(
            comm, "rpyfmm.mpi.restart_bd",
            [&](const bd::RunOptions& o) {
              return reading_file("restart_bd", checkpoint, [&] { return bd::restart_bd(checkpoint, o); });
            },
            steps, out_dir, progress);
      },
      nb::arg("comm"), nb::arg("checkpoint"), nb::arg("steps") = nb::none(), nb::arg("out_dir") = nb::none(),
      nb::arg("progress") = false,
      "Collective. rpyfmm.restart_bd across the ranks of comm, on any number of ranks whatever number\n"
      "wrote the checkpoint.");
}

}  // namespace

void bind_mpi(nb::module_& m) {
  nb::module_ sub = m.def_submodule(
      "mpi", "The MPI layer's distributed mobility operators (docs/mpi.md); use the package rpyfmm.mpi.");
  bind_distributed_direct(sub);
  bind_distributed_fmm(sub);
  bind_distributed_pse(sub);
  bind_distributed_laplace(sub);
  bind_runs(sub);
  bind_mpi_bd(sub);
  bind_mpi_partition(sub);
  bind_mpi_rigid(sub);
  sub.def("normal_noise", &normal_noise, nb::arg("n"), nb::arg("offset"), nb::arg("seed"), nb::arg("step") = 0,
          nb::arg("stream") = 0, nb::arg("out") = nb::none(),
          "Not collective. (n, 3) standard normal values of particles offset ... offset + n - 1: rows\n"
          "offset:offset + n of rpyfmm.normal_noise(N, seed, step, stream) bit for bit, so a particle's noise\n"
          "depends on its global index only (an operator's offset gives this rank's).");
}

}  // namespace rpyfmm::python
