// rpyfmm Python bindings — the CUDA PSE operator (rpy::pse::PseRpyCuda) and its products on
// device arrays (DLPack: CuPy, PyTorch, rpyfmm.cuda.to_device; see device_arrays.hpp).
//
// Host arrays take the operator's host entry points (transfers included), as every operator's.
// Device arrays take its *_device entry points, read and written in place on the current device:
// the same operations on the same vectors, so the same numbers as the host path for the same
// inputs (docs/python.md, "Device arrays"; docs/theory/pse.md). The device entry points do not
// check their inputs; the bindings check them as the host ones are checked (shapes, sizes, NaN/Inf
// by one pass on the device) before the operator runs.
#include <nanobind/stl/map.h>
#include <nanobind/stl/string.h>

#include <cmath>
#include <cstdint>
#include <type_traits>

#include "device_arrays.hpp"
#include "object_lock.hpp"
#include "rpyfmm/rpy/pse/pse_rpy_cuda.hpp"

namespace rpyfmm::python {
namespace {

using rpy::pse::PseRpyCuda;

/// op as the CUDA operator, else the refusal of device arrays on a host operator.
template <class Op>
auto& cuda_operator(Op& op, const std::string& name, const std::string& where) {
  using Cuda = std::conditional_t<std::is_const_v<Op>, const PseRpyCuda, PseRpyCuda>;
  auto* cuda = dynamic_cast<Cuda*>(&op);
  if (cuda == nullptr)
    fail(ErrorCode::invalid_input, where,
         name + " is a device array, but the '" + op.name() +
             "' operator runs on the CPU and takes host arrays: copy it to the host (cupy.asnumpy(x), x.cpu().numpy(), "
             "rpyfmm.cuda.to_host(x)), or use the CUDA PSE operator (rpyfmm.PseRpyCuda, make_mobility(..., "
             "device='cuda'))");
  return *cuda;
}

/// Checks a device argument as the host entry points check theirs: (N, 3) or (3N,) with N the
/// operator's particles, and finite values.
void require_device_points(const DeviceIn& a, std::size_t n, const std::string& where, const std::string& name) {
  const bool points = (a.shape.size() == 2 && a.shape[1] == 3) || (a.shape.size() == 1 && a.size % 3 == 0);
  require(points, ErrorCode::invalid_input, where,
          name + " has shape " + shape_string(a.shape) + ", expected (N, 3) or (3N,)");
  require(a.size == 3 * n, ErrorCode::invalid_input, where,
          name + " holds " + std::to_string(a.size / 3) + " particles, the operator " + std::to_string(n) +
              (n == 0 ? " (call set_positions with host positions first)" : ""));
  require(PseRpyCuda::device_values_finite(a.data, a.size), ErrorCode::invalid_input, where,
          name + " contains NaN or Inf");
}

/// A device argument of the operator's particles, read and checked.
DeviceIn device_points(const PseRpyCuda& op, nb::handle obj, const std::string& where, const std::string& name) {
  DeviceIn in = device_input(obj, where, name);
  require_device_points(in, op.size(), where, name);
  return in;
}

/// Checks the device result: NaN or Inf there means the inputs were beyond what the operator can
/// represent (the host path refuses such results too).
void require_finite_result(const DeviceOut& out, const std::string& where, const std::string& name) {
  require(PseRpyCuda::device_values_finite(out.data, out.size), ErrorCode::numerical_failure, where,
          name + " is not finite (NaN or Inf): inputs beyond the operator's range");
}

nb::object sample(const PseRpyCuda& op, std::uint64_t seed, std::uint64_t step, OutArg out) {
  const std::string where = "PseRpyCuda.sample";
  if (out.is_none() || !device_of(out)) {
    OutArray w = make_output(out, {op.size(), 3}, where);
    rpy::SqrtReport report;
    {
      nb::gil_scoped_release release;
      report = op.sample(seed, step, w.span());
    }
    return nb::make_tuple(w.object, report);
  }
  DeviceOut w = device_output(out, {op.size(), 3}, where, out);
  rpy::SqrtReport report;
  {
    nb::gil_scoped_release release;
    synchronize_device(where);
    report = op.sample_device(seed, step, w.data);
    synchronize_device(where);
  }
  return nb::make_tuple(w.object, report);
}

nb::object apply_with_noise(const PseRpyCuda& op, ArrayArg forces, double noise_scale, std::uint64_t seed,
                            std::uint64_t step, OutArg out) {
  const std::string where = "PseRpyCuda.apply_with_noise";
  require(std::isfinite(noise_scale), ErrorCode::invalid_argument, where, "noise_scale must be finite");
  if (!device_of(forces)) {
    const InArray f = as_input(forces, where, "forces");
    require_points(f, where, "forces");
    OutArray u = make_output(out, f.shape, where, &f);
    rpy::SqrtReport report;
    {
      nb::gil_scoped_release release;
      report = op.apply_with_noise(f.span(), noise_scale, seed, step, u.span());
    }
    return nb::make_tuple(u.object, report);
  }
  const DeviceIn f = device_points(op, forces, where, "forces");
  DeviceOut u = device_output(out, f.shape, where, forces, &f);
  rpy::SqrtReport report;
  {
    nb::gil_scoped_release release;
    synchronize_device(where);
    report = op.apply_with_noise_device(f.data, noise_scale, seed, step, u.data);
    synchronize_device(where);
  }
  require_finite_result(u, where, "the velocity");
  return nb::make_tuple(u.object, report);
}

void init_pse_cuda(PseRpyCuda* self, BoxArg box, double viscosity, double tolerance, double xi, double r_cut,
                   double window_eta, std::size_t max_memory_bytes, const std::string& wave_precision,
                   bool device_cell_list, int window_bin, bool pinned_transfers) {
  rpy::pse::PseCudaOptions cuda;
  cuda.device_cell_list = device_cell_list;
  cuda.window_bin = window_bin;
  cuda.pinned_transfers = pinned_transfers;
  new (self) PseRpyCuda(
      geometry_from(box, "PseRpyCuda"), viscosity,
      pse_options("PseRpyCuda", tolerance, xi, r_cut, window_eta, 0, max_memory_bytes, false, wave_precision, true),
      cuda);
}

}  // namespace

void set_positions_on_device(rpy::MobilityOperator& op, nb::handle positions, RadiusArg radius) {
  const std::string where = "set_positions";
  PseRpyCuda& cuda = cuda_operator(op, "positions", where);
  const DeviceIn x = device_input(positions, where, "positions");
  // The device entry point keeps the plan: same N and radius as the last host set_positions.
  const Radii r = radii_from(radius, where);
  const bool same_radius = cuda.size() > 0 && cuda.equal_radii() && r.scalar && r.values[0] == cuda.radii()[0];
  require(same_radius, ErrorCode::invalid_input, where,
          "device positions move the particles of the last set_positions with host positions (same N, same "
          "radius); call set_positions with host positions first, or give that radius");
  require_device_points(x, cuda.size(), where, "positions");
  nb::gil_scoped_release release;
  synchronize_device(where);
  cuda.set_positions_device(x.data);
  synchronize_device(where);
}

nb::object apply_on_device(const rpy::MobilityOperator& op, nb::handle forces, nb::handle torques, nb::handle out) {
  const std::string where = "apply";
  const PseRpyCuda& cuda = cuda_operator(op, "forces", where);
  const DeviceIn f = device_input(forces, where, "forces");
  require_device_points(f, cuda.size(), where, "forces");
  if (torques.is_none()) {
    DeviceOut u = device_output(out, f.shape, where, forces, &f);
    {
      nb::gil_scoped_release release;
      synchronize_device(where);
      cuda.apply_device(f.data, u.data);
      synchronize_device(where);
    }
    require_finite_result(u, where, "the velocity");
    return u.object;
  }
  require(out.is_none(), ErrorCode::invalid_argument, where, "out is not supported together with torques");
  const DeviceIn t = device_points(cuda, torques, where, "torques");
  require(t.shape == f.shape, ErrorCode::invalid_input, where,
          "torques has shape " + shape_string(t.shape) + ", expected the shape of forces " + shape_string(f.shape));
  DeviceOut u = device_output(nb::none(), f.shape, where, forces);
  DeviceOut w = device_output(nb::none(), f.shape, where, forces);
  {
    nb::gil_scoped_release release;
    synchronize_device(where);
    cuda.apply_device(f.data, t.data, u.data, w.data);
    synchronize_device(where);
  }
  require_finite_result(u, where, "the velocity");
  require_finite_result(w, where, "the angular velocity");
  return nb::make_tuple(u.object, w.object);
}

void bind_pse_cuda(nb::module_& m) {
  nb::class_<PseRpyCuda, rpy::MobilityOperator>(
      m, "PseRpyCuda",
      "Periodic RPY mobility by Positively Split Ewald on a CUDA GPU (the algorithm and results of PseRpy,\n"
      "docs/python.md, \"Device arrays\"). apply, set_positions, sample and apply_with_noise take host arrays (NumPy;\n"
      "copied to and from the device) or CUDA device arrays (CuPy, PyTorch, rpyfmm.cuda.to_device; read and\n"
      "written in place through DLPack, results in the input's framework). NotSupportedError in a build\n"
      "without CUDA or without a usable device (cuda_device_available()).")
      .def("__init__", &init_pse_cuda, nb::arg("box"), nb::arg("viscosity") = 1.0, nb::arg("tolerance") = 1e-3,
           nb::arg("xi") = 0.0, nb::arg("r_cut") = 0.0, nb::arg("window_eta") = 0.0,
           nb::arg("max_memory_bytes") = std::size_t{16} << 30, nb::arg("wave_precision") = "auto",
           nb::arg("device_cell_list") = true, nb::arg("window_bin") = 0, nb::arg("pinned_transfers") = true,
           "Options as PseRpy's; device_cell_list, window_bin and pinned_transfers as PseCudaOptions\n"
           "(rpyfmm/rpy/pse/pse_rpy_cuda.hpp).")
      .def_prop_ro("parameters",
                   locked_read(
                       "PseRpyCuda.parameters", +[](const PseRpyCuda& op) { return pse_parameters(op.parameters()); }),
                   "The choices made for the current radius, box and N.")
      .def_prop_ro(
          "device_cell_list_active",
          locked_read(
              "PseRpyCuda.device_cell_list_active", +[](const PseRpyCuda& op) { return op.device_cell_list_active(); }),
          "True when the real-space part runs on the device cell list.")
      .def("stage_times",
           locked_read(
               "PseRpyCuda.stage_times", +[](const PseRpyCuda& op) { return op.stage_times(); }),
           "Accumulated seconds per stage (CUDA events).")
      .def("sample", locked("PseRpyCuda.sample", &sample), nb::arg("seed"), nb::arg("step") = 0,
           nb::arg("out") = nb::none(),
           "w = M^{1/2} z by the split sampler keyed by (seed, step): (w (N, 3), SqrtReport). A device array\n"
           "`out` is written on the device.")
      .def("apply_with_noise", locked("PseRpyCuda.apply_with_noise", &apply_with_noise), nb::arg("forces"),
           nb::arg("noise_scale"), nb::arg("seed"), nb::arg("step") = 0, nb::arg("out") = nb::none(),
           "U = M F + noise_scale M^{1/2} z in one fused pass: (U, SqrtReport); device forces give a device U.");
}

}  // namespace rpyfmm::python
