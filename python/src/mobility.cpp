// rpyfmm Python bindings — the mobility operators behind the one interface
// rpy::MobilityOperator (rpy/include/rpyfmm/rpy/mobility.hpp): DirectRpy,
// FmmRpy, pse::PseRpy, rpy::FreeDrainingMobility and rpy::make_mobility.
//
// Units are the caller's: with viscosity eta and radius a, M_ii = 1/(6 pi eta a);
// velocities U = M F have units of force / (viscosity length).
#include <nanobind/stl/map.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/unique_ptr.h>
#include <nanobind/stl/vector.h>

#include "common.hpp"
#include "device_arrays.hpp"
#include "object_lock.hpp"
#include "rpyfmm/core/threads.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"
#include "rpyfmm/rpy/free_draining.hpp"
#include "rpyfmm/rpy/mobility_factory.hpp"
#include "rpyfmm/rpy/pse/open_pse_rpy.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/pse/pse_rpy_cuda.hpp"

namespace rpyfmm::python {
namespace {

using rpy::MobilityOperator;

void set_positions(MobilityOperator& op, ArrayArg positions, RadiusArg radius) {
  if (device_of(positions)) return set_positions_on_device(op, positions, radius);
  const std::string where = "set_positions";
  const InArray x = as_input(positions, where, "positions");
  require_points(x, where, "positions");
  if (is_array_like(radius)) {
    const InArray r = as_input(radius, where, "radii");
    require(r.ndim() == 1, ErrorCode::invalid_input, where,
            "radii has shape " + shape_string(r.shape) + ", expected (N,)");
    nb::gil_scoped_release release;
    op.set_positions(x.span(), r.span());
    return;
  }
  double a = 0.0;
  if (!nb::try_cast(radius.h, a, true)) {
    fail(ErrorCode::invalid_argument, where, "radius must be a number or an array of N radii");
  }
  nb::gil_scoped_release release;
  op.set_positions(x.span(), a);
}

/// The shape of every U = A F binding: forces (N, 3) or (3N,) in, the same shape out, GIL released.
template <class Fn>
ArrayResult map_points(const std::string& where, ArrayArg forces, OutArg out, Fn&& fn) {
  const InArray f = as_input(forces, where, "forces");
  require_points(f, where, "forces");
  OutArray u = make_output(out, f.shape, where, &f);
  {
    nb::gil_scoped_release release;
    fn(f.span(), u.span());
  }
  return ArrayResult{u.object};
}

/// U = M F; with torques, (U, W) = M (F, T) (MobilityOperator::apply with rotation).
nb::object apply(const MobilityOperator& op, ArrayArg forces, OptArrayArg torques, OutArg out) {
  if (device_of(forces)) return apply_on_device(op, forces, torques, out);
  if (torques.is_none()) return map_points("apply", forces, out, [&](auto f, auto u) { op.apply(f, u); }).o;
  const RotationArrays a = rotation_arrays(forces, torques, out, "apply");
  {
    nb::gil_scoped_release release;
    op.apply(a.f.span(), a.t.span(), a.u.span(), a.w.span());
  }
  return nb::make_tuple(a.u.object, a.w.object);
}

ArrayResult apply_block(const MobilityOperator& op, ArrayArg forces, OutArg out) {
  const std::string where = "apply_block";
  const InArray f = as_input(forces, where, "forces");
  const std::size_t nrhs = block_count(f, where, "forces");
  OutArray u = make_output(out, f.shape, where, &f);
  {
    nb::gil_scoped_release release;
    op.apply_block(f.span(), u.span(), nrhs);
  }
  return ArrayResult{u.object};
}

/// apply_sqrt (Block = false) and apply_sqrt_block (Block = true): `tol` is the deprecated spelling
/// of `tolerance`.
template <bool Block>
ArrayAndReport<rpy::SqrtReport> apply_sqrt(const MobilityOperator& op, ArrayArg z, OutArg out,
                                           const std::string& method, std::optional<double> tolerance,
                                           int max_iterations, bool reorthogonalize, bool throw_if_not_converged,
                                           double lambda_min, double lambda_max, int bound_estimate_iterations,
                                           const std::string& preconditioner, int preconditioner_block,
                                           std::optional<double> tol) {
  const std::string where = Block ? "apply_sqrt_block" : "apply_sqrt";
  const double t = renamed_keyword(tolerance, tol, rpy::SqrtOptions{}.tolerance, where, "tolerance", "tol");
  const rpy::SqrtOptions o =
      sqrt_options(method, t, max_iterations, reorthogonalize, throw_if_not_converged, lambda_min, lambda_max,
                   bound_estimate_iterations, preconditioner, preconditioner_block);
  const InArray zz = as_input(z, where, "z");
  const std::size_t nrhs = Block ? block_count(zz, where, "z") : (require_points(zz, where, "z"), 1);
  OutArray w = make_output(out, zz.shape, where, &zz);
  rpy::SqrtReport report;
  {
    nb::gil_scoped_release release;
    report = Block ? op.apply_sqrt_block(zz.span(), w.span(), nrhs, o) : op.apply_sqrt(zz.span(), w.span(), o);
  }
  return array_and_report(w.object, report);
}

/// [w_t; w_r] = B [z_t; z_r], B B^T = the grand mobility (MobilityOperator::apply_sqrt_rotation).
RotationSample apply_sqrt_rotation(const MobilityOperator& op, ArrayArg z_translation, ArrayArg z_rotation,
                                   const std::string& method, std::optional<double> tolerance, int max_iterations,
                                   bool reorthogonalize, bool throw_if_not_converged, double lambda_min,
                                   double lambda_max, int bound_estimate_iterations, const std::string& preconditioner,
                                   int preconditioner_block) {
  const std::string where = "apply_sqrt_rotation";
  const rpy::SqrtOptions o = sqrt_options(method, tolerance.value_or(rpy::SqrtOptions{}.tolerance), max_iterations,
                                          reorthogonalize, throw_if_not_converged, lambda_min, lambda_max,
                                          bound_estimate_iterations, preconditioner, preconditioner_block);
  const RotationArrays a = paired_arrays(z_translation, z_rotation, where, "z_translation", "z_rotation");
  rpy::SqrtReport report;
  {
    nb::gil_scoped_release release;
    report = op.apply_sqrt_rotation(a.f.span(), a.t.span(), a.u.span(), a.w.span(), o);
  }
  return rotation_sample(a, report);
}

const char* kSqrtDoc =
    "w = M^{1/2} z for z of shape (N, 3) or (3N,). Returns (w, SqrtReport).\n\n"
    "method: 'auto' (the operator's preferred: PSE split sampler, else Lanczos), 'lanczos', 'chebyshev',\n"
    "'cholesky' (L z with L L^T = M), 'eigen' (dense principal root), 'split' (PSE only).\n"
    "tolerance: relative tolerance in (0, 1) (tol: its deprecated spelling); max_iterations: 0 = automatic;\n"
    "lambda_min/lambda_max: Chebyshev bounds (both 0 = estimated). w has units of sqrt(mobility) times z's\n"
    "units.\n"
    "preconditioner: 'none' (w = M^{1/2} z), 'block' (Lanczos and Chebyshev: w = B z with B B^T = M, the\n"
    "same covariance in fewer products; spatial blocks of at most preconditioner_block particles,\n"
    "0 = N/64 in [16, 32]; given Chebyshev bounds must then bound G M G^T) or 'auto' (block for Lanczos\n"
    "and for Chebyshev with estimated bounds, else none).";

using OperatorClass = nb::class_<MobilityOperator>;

/// MobilityOperator's state: name, geometry, particles, repr.
void add_operator_state(OperatorClass& cls) {
  cls.def_prop_ro("name", &MobilityOperator::name, "Solver name: 'direct', 'fmm', 'pse', 'none'.")
      .def_prop_ro("viscosity", &MobilityOperator::viscosity, "Solvent viscosity eta.")
      .def_prop_ro(
          "box", [](const MobilityOperator& op) { return box_tuple(op.geometry()); },
          "(Lx, Ly, Lz) of the periodic box, or None in free space.")
      .def_prop_ro(
          "periodic", [](const MobilityOperator& op) { return op.geometry().is_periodic(); }, "True in a periodic box.")
      .def_prop_ro("size",
                   locked_read(
                       "MobilityOperator.size", +[](const MobilityOperator& op) { return op.size(); }),
                   "Number of particles N (0 before set_positions).")
      .def("__len__",
           locked_read(
               "MobilityOperator.__len__", +[](const MobilityOperator& op) { return op.size(); }),
           "N, as size.")
      .def_prop_ro("equal_radii",
                   locked_read(
                       "MobilityOperator.equal_radii", +[](const MobilityOperator& op) { return op.equal_radii(); }),
                   "True when every particle has the same radius.")
      .def_prop_ro("positions",
                   locked_read(
                       "MobilityOperator.positions",
                       +[](const MobilityOperator& op) {
                         auto p = op.positions();
                         return adopt_vector(std::vector<double>(p.begin(), p.end()), {p.size() / 3, 3});
                       }),
                   "Copy of the stored positions (N, 3) (wrapped into the box when periodic).")
      .def_prop_ro("radii",
                   locked_read(
                       "MobilityOperator.radii",
                       +[](const MobilityOperator& op) {
                         auto r = op.radii();
                         return adopt_vector(std::vector<double>(r.begin(), r.end()), {r.size()});
                       }),
                   "Copy of the radii (N,).")
      .def("__repr__", locked_read(
                           "MobilityOperator.__repr__", +[](const MobilityOperator& op) {
                             return "<rpyfmm." + op.name() + " mobility, N = " + std::to_string(op.size()) +
                                    ", viscosity = " + std::to_string(op.viscosity()) +
                                    (op.geometry().is_periodic() ? ", periodic>" : ">");
                           }));
}

/// apply_sqrt or apply_sqrt_block with their keywords (the same for both).
template <bool Block>
void add_apply_sqrt(OperatorClass& cls, const char* name, const char* where, const char* doc) {
  cls.def(name, locked(where, &apply_sqrt<Block>), nb::arg("z"), nb::arg("out") = nb::none(), nb::kw_only(),
          nb::arg("method") = "auto", nb::arg("tolerance").sig("0.001") = nb::none(), nb::arg("max_iterations") = 0,
          nb::arg("reorthogonalize") = true, nb::arg("throw_if_not_converged") = true, nb::arg("lambda_min") = 0.0,
          nb::arg("lambda_max") = 0.0, nb::arg("bound_estimate_iterations") = 30, nb::arg("preconditioner") = "none",
          nb::arg("preconditioner_block") = 0, nb::arg("tol") = nb::none(), doc);
}

ArrayResult divergence(const MobilityOperator& op) {
  std::vector<double> d(3 * op.size());
  op.divergence(d);
  return adopt_vector(std::move(d), {op.size(), 3});
}

ArrayResult assemble_dense(const MobilityOperator& op, std::size_t max_bytes) {
  std::vector<double> dense;
  {
    nb::gil_scoped_release release;
    dense = op.assemble_dense(max_bytes);
  }
  const std::size_t n = 3 * op.size();
  return adopt_vector(std::move(dense), {n, n});
}

/// MobilityOperator's products: set_positions, M F, M^{1/2} z, divergence, dense matrix.
void add_operator_products(OperatorClass& cls) {
  cls.def("set_positions", locked("MobilityOperator.set_positions", &set_positions), nb::arg("positions"),
          nb::arg("radius"),
          "Sets positions ((N, 3) or (3N,), length units) and the radius: one number for all particles or an\n"
          "array of N radii. Builds the solver's plan once; apply may then be called many times.")
      .def("apply", locked("MobilityOperator.apply", &apply), nb::arg("forces"), nb::arg("torques") = nb::none(),
           nb::arg("out") = nb::none(),
           "U = M F. forces: (N, 3) or (3N,); returns velocities in the same shape (float64);\n"
           "`out` (writable float64, C-contiguous) is written in place and returned.\n"
           "With torques (same shape as forces): returns (U, W) = M (F, T), the velocities and angular\n"
           "velocities of the grand mobility with rotation (operators with supports_rotation only).")
      .def_prop_ro(
          "supports_rotation", [](const MobilityOperator& op) { return op.supports_rotation(); },
          "True when apply accepts torques and apply_sqrt_rotation samples (the grand mobility with\n"
          "rotation: DirectRpy, FmmRpy, PseRpy, FreeDraining).")
      .def("apply_block", locked("MobilityOperator.apply_block", &apply_block), nb::arg("forces"),
           nb::arg("out") = nb::none(), "U_k = M F_k for forces of shape (nrhs, N, 3) or (nrhs, 3N) in one pass.");
  add_apply_sqrt<false>(cls, "apply_sqrt", "MobilityOperator.apply_sqrt", kSqrtDoc);
  add_apply_sqrt<true>(
      cls, "apply_sqrt_block", "MobilityOperator.apply_sqrt_block",
      "Block apply_sqrt: z of shape (nrhs, N, 3) or (nrhs, 3N), one operator product per iteration for all.");
  cls.def("apply_sqrt_rotation", locked("MobilityOperator.apply_sqrt_rotation", &apply_sqrt_rotation),
          nb::arg("z_translation"), nb::arg("z_rotation"), nb::kw_only(), nb::arg("method") = "auto",
          nb::arg("tolerance").sig("0.001") = nb::none(), nb::arg("max_iterations") = 0,
          nb::arg("reorthogonalize") = true, nb::arg("throw_if_not_converged") = true, nb::arg("lambda_min") = 0.0,
          nb::arg("lambda_max") = 0.0, nb::arg("bound_estimate_iterations") = 30, nb::arg("preconditioner") = "none",
          nb::arg("preconditioner_block") = 0,
          "Brownian displacements and rotations: (w_t, w_r) = B (z_t, z_r) with B B^T = the grand mobility\n"
          "(operators with supports_rotation only). z_translation, z_rotation: (N, 3) or (3N,), the same shape.\n"
          "Returns (w_t, w_r, SqrtReport), w_t and w_r in z's shape.\n\n"
          "The sampler runs on S M S, S = diag(1, a_i) per particle, so that the tolerance weighs translations\n"
          "and rotations (times the radius) alike; B = S^{-1} (S M S)^{1/2} (the principal root for unit radii).\n"
          "Keywords as apply_sqrt ('block' preconditions with 6 x 6 per-particle blocks; given Chebyshev bounds\n"
          "are those of S M S); free draining samples exactly (docs/theory/samplers.md, 'Rotation').");
  cls.def("divergence", locked("MobilityOperator.divergence", &divergence),
          "Divergence of M with respect to the positions, (N, 3); zero for RPY.")
      .def("assemble_dense", locked("MobilityOperator.assemble_dense", &assemble_dense),
           nb::arg("max_bytes") = std::size_t{1} << 31,
           "Dense (3N, 3N) matrix from products with unit vectors (small N only).");
}

void bind_mobility_operator(nb::module_& m) {
  OperatorClass cls(
      m, "MobilityOperator",
      "The one RPY mobility interface: U = M F for N spheres (MobilityOperator in C++).\n\n"
      "Positions, forces and velocities are (N, 3) or (3N,) arrays (particle-major). Units are the caller's:\n"
      "with viscosity eta and radius a, the self mobility is 1/(6 pi eta a).");
  add_operator_state(cls);
  add_operator_products(cls);
}

void bind_direct_rpy(nb::module_& m) {
  nb::class_<rpy::DirectRpy, MobilityOperator>(m, "DirectRpy",
                                               "Exact O(N^2) RPY mobility (all overlap regimes); free space only.")
      .def(
          "__init__",
          [](rpy::DirectRpy* self, double viscosity, BoxArg box) {
            new (self) rpy::DirectRpy(geometry_from(box, "DirectRpy"), viscosity);
          },
          nb::arg("viscosity") = 1.0, nb::arg("box") = nb::none(),
          "viscosity: eta > 0; box must be None (a periodic box raises NotSupportedError).");
}

void bind_fmm_rpy(nb::module_& m) {
  nb::class_<rpy::FmmRpy, MobilityOperator>(
      m, "FmmRpy", "Free-space RPY mobility in O(N): one multi-density Laplace FMM pass plus the exact near field.")
      .def(
          "__init__",
          [](rpy::FmmRpy* self, double viscosity, double tolerance, int leaf_capacity, BoxArg box) {
            rpy::FmmRpyOptions o;
            o.tolerance = tolerance;
            o.leaf_capacity = leaf_capacity;
            new (self) rpy::FmmRpy(geometry_from(box, "FmmRpy"), viscosity, o);
          },
          nb::arg("viscosity") = 1.0, nb::arg("tolerance") = 1e-6, nb::arg("leaf_capacity") = 0,
          nb::arg("box") = nb::none(),
          "tolerance: relative l2 error of U in [1e-12, 1e-1]; leaf_capacity: 0 = automatic.")
      .def_prop_ro(
          "tolerance", [](const rpy::FmmRpy& op) { return op.options().tolerance; },
          "Requested relative l2 error of U.")
      .def_prop_ro("laplace_tolerance",
                   locked_read(
                       "FmmRpy.laplace_tolerance", +[](const rpy::FmmRpy& op) { return op.laplace_eps(); }),
                   "Tolerance handed to the Laplace FMM.")
      .def_prop_ro("laplace_eps",
                   locked_read(
                       "FmmRpy.laplace_eps",
                       +[](const rpy::FmmRpy& op) {
                         warn_deprecated("FmmRpy.laplace_eps is deprecated; use FmmRpy.laplace_tolerance");
                         return op.laplace_eps();
                       }),
                   "Deprecated spelling of laplace_tolerance (DeprecationWarning).")
      .def("last_timings",
           locked_read(
               "FmmRpy.last_timings", +[](const rpy::FmmRpy& op) { return op.last_timings(); }),
           "Stage times (s) of the last apply.")
      .def("stats",
           locked_read(
               "FmmRpy.stats",
               +[](const rpy::FmmRpy& op) {
                 return op.laplace_plan() ? tree_stats_dict(op.laplace_plan()->stats()) : nb::dict();
               }),
           "The Laplace FMM tree's statistics (as LaplaceFmm.stats()); empty before set_positions.");
}

void init_pse_rpy(rpy::pse::PseRpy* self, BoxArg box, double viscosity, double tolerance, double xi, double r_cut,
                  double window_eta, int fft_threads, std::size_t max_memory_bytes, bool fft_measure,
                  const std::string& wave_precision, bool real_space_cache) {
  new (self) rpy::pse::PseRpy(geometry_from(box, "PseRpy"), viscosity,
                              pse_options("PseRpy", tolerance, xi, r_cut, window_eta, fft_threads, max_memory_bytes,
                                          fft_measure, wave_precision, real_space_cache));
}

using PseClass = nb::class_<rpy::pse::PseRpy, MobilityOperator>;

/// PseRpy's construction, parameters and stage times.
void add_pse_state(PseClass& cls) {
  cls.def("__init__", &init_pse_rpy, nb::arg("box"), nb::arg("viscosity") = 1.0, nb::arg("tolerance") = 1e-3,
          nb::arg("xi") = 0.0, nb::arg("r_cut") = 0.0, nb::arg("window_eta") = 0.0, nb::arg("fft_threads") = 0,
          nb::arg("max_memory_bytes") = std::size_t{16} << 30, nb::arg("fft_measure") = false,
          nb::arg("wave_precision") = "auto", nb::arg("real_space_cache") = true,
          "box: L (cube) or (Lx, Ly, Lz), length units; tolerance in [1e-8, 0.1) relative to 1/(6 pi eta a);\n"
          "xi: Ewald splitting (1/length, 0 = automatic); r_cut: real-space cutoff (length, 0 = automatic);\n"
          "window_eta: Gaussian window shape in (0, 1), 0 = the cheapest meeting the tolerance;\n"
          "fft_threads: FFTW threads (0 = automatic: the OpenMP threads for grids of >= 2^20 points, else one;\n"
          "at most 4 x the hardware threads);\n"
          "fft_measure: FFTW_MEASURE plans (timed at set_positions, faster transforms, results\n"
          "reproducible to round-off rather than bit for bit across processes);\n"
          "wave_precision: 'single' or 'double' wave-space grids; 'auto' = single for tolerance >= 1e-5\n"
          "(adds ~1e-7 relative error, faster FFTs and half the grid memory);\n"
          "real_space_cache: keep each real-space pair's block from the first product after set_positions\n"
          "for the later ones (the split sampler's Lanczos); float with single wave grids, else double,\n"
          "while it fits in max_memory_bytes (parameters['real_space_cache_bytes']).")
      .def_prop_ro(
          "parameters",
          locked_read(
              "PseRpy.parameters", +[](const rpy::pse::PseRpy& op) { return pse_parameters(op.parameters()); }),
          "The choices made for the current radius, box and N (xi, r_cut, grid, support, ...).")
      .def("stage_times",
           locked_read(
               "PseRpy.stage_times", +[](const rpy::pse::PseRpy& op) { return op.stage_times(); }),
           "Accumulated seconds per stage.")
      .def("reset_stage_times",
           locked(
               "PseRpy.reset_stage_times", +[](rpy::pse::PseRpy& op) { op.reset_stage_times(); }),
           "Sets the accumulated stage times to zero.");
}

/// The split sampler keyed by (seed, step), for PseRpy and OpenPseRpy.
template <class Op>
ArrayAndReport<rpy::SqrtReport> pse_sample(const Op& op, std::uint64_t seed, std::uint64_t step, OutArg out) {
  OutArray w = make_output(out, {op.size(), 3}, "sample");
  rpy::SqrtReport report;
  {
    nb::gil_scoped_release release;
    report = op.sample(seed, step, w.span());
  }
  return array_and_report(w.object, report);
}

/// The fused drift-and-noise pass, for PseRpy and OpenPseRpy.
template <class Op>
ArrayAndReport<rpy::SqrtReport> pse_apply_with_noise(const Op& op, ArrayArg forces, double noise_scale,
                                                     std::uint64_t seed, std::uint64_t step, OutArg out) {
  const InArray f = as_input(forces, "apply_with_noise", "forces");
  require_points(f, "apply_with_noise", "forces");
  OutArray u = make_output(out, f.shape, "apply_with_noise", &f);
  rpy::SqrtReport report;
  {
    nb::gil_scoped_release release;
    report = op.apply_with_noise(f.span(), noise_scale, seed, step, u.span());
  }
  return array_and_report(u.object, report);
}

/// PseRpy's own products: the real- and wave-space parts, the split sampler, the fused BD pass.
void add_pse_products(PseClass& cls) {
  cls.def("apply_real",
          locked(
              "PseRpy.apply_real",
              +[](const rpy::pse::PseRpy& op, ArrayArg forces, OutArg out) {
                return map_points("apply_real", forces, out, [&](auto f, auto u) { op.apply_real(f, u); });
              }),
          nb::arg("forces"), nb::arg("out") = nb::none(), "U = M_r F (real-space part).")
      .def("apply_wave",
           locked(
               "PseRpy.apply_wave",
               +[](const rpy::pse::PseRpy& op, ArrayArg forces, OutArg out) {
                 return map_points("apply_wave", forces, out, [&](auto f, auto u) { op.apply_wave(f, u); });
               }),
           nb::arg("forces"), nb::arg("out") = nb::none(), "U = M_w F (wave-space part).")
      .def("sample", locked("PseRpy.sample", &pse_sample<rpy::pse::PseRpy>), nb::arg("seed"), nb::arg("step") = 0,
           nb::arg("out") = nb::none(),
           "w = M^{1/2} z by the split sampler with noise keyed by (seed, step). Returns (w (N, 3), SqrtReport).")
      .def("apply_with_noise", locked("PseRpy.apply_with_noise", &pse_apply_with_noise<rpy::pse::PseRpy>),
           nb::arg("forces"), nb::arg("noise_scale"), nb::arg("seed"), nb::arg("step") = 0, nb::arg("out") = nb::none(),
           "U = M F + noise_scale M^{1/2} z in one fused pass (BD: noise_scale = sqrt(2 kT / dt)).");
}

void bind_pse_rpy(nb::module_& m) {
  PseClass cls(m, "PseRpy",
               "Periodic RPY mobility by Positively Split Ewald (Fiore et al. 2017), equal radii.\n\n"
               "apply_sqrt with method 'auto'/'split' uses the split sampler: z is z1, the wave-space noise is\n"
               "seeded by a hash of z, so w is a deterministic function of z with covariance M.");
  add_pse_state(cls);
  add_pse_products(cls);
}

void init_open_pse_rpy(rpy::pse::OpenPseRpy* self, double viscosity, double tolerance, double xi, double r_cut,
                       double window_eta, int fft_threads, std::size_t max_memory_bytes, bool fft_measure,
                       const std::string& wave_precision, bool real_space_cache) {
  new (self)
      rpy::pse::OpenPseRpy(viscosity, pse_options("OpenPseRpy", tolerance, xi, r_cut, window_eta, fft_threads,
                                                  max_memory_bytes, fft_measure, wave_precision, real_space_cache));
}

void bind_open_pse_rpy(nb::module_& m) {
  using Op = rpy::pse::OpenPseRpy;
  nb::class_<Op, MobilityOperator>(
      m, "OpenPseRpy",
      "RPY mobility in free space by Positively Split Ewald with open boundaries (docs/theory/pse.md,\n"
      "section 6), equal radii: the periodic grid follows the particles, and the wave-space kernel is\n"
      "compactly supported and positive, so the split sampler gives a Brownian displacement for about\n"
      "the cost of one product. apply_sqrt with 'auto'/'split' as PseRpy.")
      .def("__init__", &init_open_pse_rpy, nb::arg("viscosity") = 1.0, nb::arg("tolerance") = 1e-3, nb::arg("xi") = 0.0,
           nb::arg("r_cut") = 0.0, nb::arg("window_eta") = 0.0, nb::arg("fft_threads") = 0,
           nb::arg("max_memory_bytes") = std::size_t{16} << 30, nb::arg("fft_measure") = false,
           nb::arg("wave_precision") = "auto", nb::arg("real_space_cache") = true,
           "Options as PseRpy's, without a box: it is chosen from the particles' extent at set_positions.")
      .def_prop_ro("parameters",
                   locked_read(
                       "OpenPseRpy.parameters", +[](const Op& op) { return pse_parameters(op.parameters()); }),
                   "The choices of the current plan (xi, r_cut, grid, ..., open_truncation = R).")
      .def_prop_ro("box",
                   locked_read(
                       "OpenPseRpy.box",
                       +[](const Op& op) {
                         const auto b = op.box();
                         return nb::make_tuple(b[0], b[1], b[2]);
                       }),
                   "The periodic box of the current plan (Lx, Ly, Lz).")
      .def_prop_ro("constant_part",
                   locked_read(
                       "OpenPseRpy.constant_part", +[](const Op& op) { return op.constant_part(); }),
                   "c = 1 / (4 pi eta R): the common translation's part of M.")
      .def("stage_times",
           locked_read(
               "OpenPseRpy.stage_times", +[](const Op& op) { return op.stage_times(); }),
           "Accumulated seconds per stage.")
      .def("reset_stage_times",
           locked(
               "OpenPseRpy.reset_stage_times", +[](Op& op) { op.reset_stage_times(); }),
           "Sets the accumulated stage times to zero.")
      .def("sample", locked("OpenPseRpy.sample", &pse_sample<Op>), nb::arg("seed"), nb::arg("step") = 0,
           nb::arg("out") = nb::none(),
           "w = M^{1/2} z by the split sampler with noise keyed by (seed, step). Returns (w (N, 3), SqrtReport).")
      .def("apply_with_noise", locked("OpenPseRpy.apply_with_noise", &pse_apply_with_noise<Op>), nb::arg("forces"),
           nb::arg("noise_scale"), nb::arg("seed"), nb::arg("step") = 0, nb::arg("out") = nb::none(),
           "U = M F + noise_scale M^{1/2} z in one fused pass (BD: noise_scale = sqrt(2 kT / dt)).");
}

void bind_free_draining(nb::module_& m) {
  nb::class_<rpy::FreeDrainingMobility, MobilityOperator>(
      m, "FreeDraining",
      "No hydrodynamic interactions: M = diag(1 / (6 pi eta a_i)), with rotation 1 / (8 pi eta a_i^3);\n"
      "exact square roots.")
      .def(
          "__init__",
          [](rpy::FreeDrainingMobility* self, double viscosity, BoxArg box) {
            new (self) rpy::FreeDrainingMobility(geometry_from(box, "FreeDraining"), viscosity);
          },
          nb::arg("viscosity") = 1.0, nb::arg("box") = nb::none(),
          "viscosity: eta > 0; box: None, L or (Lx, Ly, Lz) (the diagonal mobility does not depend on it).");
}

/// make_mobility and its helpers, as BD configs and the CLI build operators.
void bind_mobility_factory(nb::module_& m) {
  m.def(
      "make_mobility",
      [](const std::string& method, std::size_t n_particles, double tolerance, double viscosity, BoxArg box,
         std::size_t fmm_crossover, const std::string& device) {
        rpy::MobilitySpec spec;
        spec.method = rpy::mobility_method_from_string(method);
        spec.tolerance = tolerance;
        spec.viscosity = viscosity;
        spec.geometry = geometry_from(box, "make_mobility");
        spec.fmm_crossover = fmm_crossover;
        spec.device = rpy::compute_device_from_string(device, "make_mobility");
        return rpy::make_mobility(spec, n_particles);
      },
      nb::arg("method") = "auto", nb::arg("n_particles") = 0, nb::kw_only(), nb::arg("tolerance") = 1e-3,
      nb::arg("viscosity") = 1.0, nb::arg("box") = nb::none(), nb::arg("fmm_crossover") = 0, nb::arg("device") = "cpu",
      "Builds an operator by name as BD configs and the CLI do: 'none', 'direct', 'fmm', 'pse', 'auto'\n"
      "(open: direct below fmm_crossover particles, else fmm; periodic: pse). fmm_crossover = 0:\n"
      "default_fmm_crossover(tolerance). device 'cuda': the pse operator on a GPU (a build with CUDA\n"
      "and a usable device, see cuda_device_available(); other methods refuse it).");
  m.def("cuda_device_available", &rpy::pse::PseRpyCuda::device_available,
        "True when this build has the CUDA PSE backend and a usable GPU (make_mobility(..., device='cuda')).");
  m.def("default_fmm_crossover", &rpy::default_fmm_crossover, nb::arg("tolerance") = 1e-3,
        "Particle count from which 'auto' picks fmm over direct at this tolerance on this machine\n"
        "(measured crossover of one product, larger where the AVX-512 direct kernels run).");

  // Benchmark helper (bench/python/bench_overhead.py): the C++ call timed in C++,
  // without any Python in the loop. Seconds per call, `repeats` calls.
  m.def(
      "_time_apply_cpp",
      [](const MobilityOperator& op, ArrayArg forces, OutArg out, int repeats) {
        const CallGuard hold = guard("_time_apply_cpp", op);
        const InArray f = as_input(forces, "_time_apply_cpp", "forces");
        OutArray u = make_output(out, f.shape, "_time_apply_cpp", &f);
        std::vector<double> seconds;
        nb::gil_scoped_release release;
        for (int r = 0; r < repeats; ++r) {
          StopWatch watch;
          op.apply(f.span(), u.span());
          seconds.push_back(watch.seconds());
        }
        return seconds;
      },
      nb::arg("op"), nb::arg("forces"), nb::arg("out"), nb::arg("repeats") = 5);
}

}  // namespace

RotationArrays paired_arrays(ArrayArg first, ArrayArg second, const std::string& where, const std::string& first_name,
                             const std::string& second_name) {
  InArray f = as_input(first, where, first_name);
  InArray t = as_input(second, where, second_name);
  require_points(f, where, first_name);
  require(t.shape == f.shape, ErrorCode::invalid_input, where,
          second_name + " has shape " + shape_string(t.shape) + ", expected the shape of " + first_name + " " +
              shape_string(f.shape));
  OutArray u = make_output(nb::none(), f.shape, where);
  OutArray w = make_output(nb::none(), f.shape, where);
  return RotationArrays{std::move(f), std::move(t), std::move(u), std::move(w)};
}

RotationArrays rotation_arrays(ArrayArg forces, OptArrayArg torques, OutArg out, const std::string& where) {
  require(out.is_none(), ErrorCode::invalid_argument, where, "out is not supported together with torques");
  return paired_arrays(forces, ArrayArg{torques.h}, where, "forces", "torques");
}

nb::dict pse_parameters(const rpy::pse::PseParameters& p) {
  nb::dict d;
  d["radius"] = p.radius;
  d["xi"] = p.xi;
  d["xi_automatic"] = p.xi_automatic;
  d["tolerance"] = p.tolerance;
  d["r_cut"] = p.r_cut;
  d["grid"] = nb::make_tuple(p.grid[0], p.grid[1], p.grid[2]);
  d["spacing"] = nb::make_tuple(p.spacing[0], p.spacing[1], p.spacing[2]);
  d["support"] = nb::make_tuple(p.support[0], p.support[1], p.support[2]);
  d["window_eta"] = p.window_eta;
  d["eta_automatic"] = p.eta_automatic;
  d["sigma"] = p.sigma;
  d["window_m"] = p.window_m;
  d["table_dr"] = p.table_dr;
  d["table_size"] = p.table_size;
  d["lanczos_tolerance"] = p.lanczos_tolerance;
  d["wave_precision"] = p.wave_single ? "single" : "double";
  d["memory_bytes"] = p.memory_bytes;
  d["real_space_cache_bytes"] = p.real_space_cache_bytes;
  d["modelled_cost"] = p.modelled_cost;
  d["open_truncation"] = p.open_truncation;  // R of the open-boundary kernel (0: periodic)
  d["summary"] = p.summary();
  return d;
}

rpy::pse::PseOptions pse_options(const char* where, double tolerance, double xi, double r_cut, double window_eta,
                                 int fft_threads, std::size_t max_memory_bytes, bool fft_measure,
                                 const std::string& wave_precision, bool real_space_cache) {
  rpy::pse::PseOptions o;
  o.tolerance = tolerance;
  o.xi = xi;
  o.r_cut = r_cut;
  o.window_eta = window_eta;
  require_thread_count(fft_threads, std::string(where) + " fft_threads", true);
  o.fft_threads = fft_threads;
  o.max_memory_bytes = max_memory_bytes;
  o.fft_measure = fft_measure;
  o.wave_precision = rpy::pse::wave_precision_from_name(wave_precision, where);
  o.real_space_cache = real_space_cache;
  return o;
}

void bind_mobility(nb::module_& m) {
  bind_mobility_operator(m);
  bind_direct_rpy(m);
  bind_fmm_rpy(m);
  bind_pse_rpy(m);
  bind_open_pse_rpy(m);
  bind_free_draining(m);
  bind_mobility_factory(m);
}

}  // namespace rpyfmm::python
