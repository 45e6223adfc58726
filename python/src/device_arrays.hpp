// rpyfmm Python bindings — device arrays through DLPack (docs/python.md, "Device arrays").
//
// An argument is a device array when its `__dlpack_device__()` names a device other than the
// host (DLPack's kDLCPU = 1): CuPy arrays, PyTorch CUDA tensors, JAX arrays on a GPU, and the
// arrays rpyfmm.cuda.to_device returns. The CUDA PSE operator (PseRpyCuda) reads and writes them
// in place: a float64, C-contiguous CUDA array on the current device is passed to its *_device
// entry points as a pointer, with no host copy (pse_cuda.cpp). Every other call takes host arrays
// and refuses a device array with a message that names it and says how to copy it (as_input).
// The device BD engine's positions and forces leave as read-only views (read_only_view, bd.cpp).
//
// Streams: the operator runs on CUDA's legacy default stream. Before it reads a caller's device
// array and before it hands results back, the whole device is synchronised, so work that CuPy or
// PyTorch queued on their own streams is complete and theirs sees the results (one
// cudaDeviceSynchronize each way, microseconds beside a PSE product).
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "common.hpp"
#include "rpyfmm/rpy/mobility.hpp"

namespace rpyfmm::python {

/// DLPack's device of an array: type (kDLCUDA = 2, kDLCUDAManaged = 13, ...) and ordinal.
struct DlpackDevice {
  int type = 1;
  int id = 0;
};

/// The device of `obj` when it is an array on a device other than the host (its
/// __dlpack_device__() reports a type other than kDLCPU); std::nullopt for host arrays and for
/// objects without __dlpack_device__ (lists, numbers, ...).
std::optional<DlpackDevice> device_of(nb::handle obj);

/// "cuda:0", "cuda_managed:1", "rocm:0", or "device type T:i" for others.
std::string device_name(const DlpackDevice& device);

/// The message of a device array passed where host arrays are taken (names `name`, its device and
/// the ways to copy it to the host or use the CUDA operator).
std::string device_array_refusal(const std::string& name, const DlpackDevice& device);

/// A float64 C-contiguous CUDA array argument on the current device, read in place.
struct DeviceIn {
  nb::object owner;  ///< the argument: keeps its memory alive
  const double* data = nullptr;
  std::size_t size = 0;
  std::vector<std::size_t> shape;
};

/// Reads `obj` as a float64 C-contiguous CUDA array on the current device; rpyfmm::Error naming
/// `where` and `name` otherwise (another dtype, strides, device or device type, a build without
/// CUDA).
DeviceIn device_input(nb::handle obj, const std::string& where, const std::string& name);

/// A device output: the caller's `out` (a writable float64 C-contiguous CUDA array on the current
/// device with the right number of entries) or a new array of `shape` allocated on the current
/// device, returned in the framework of `like` (a torch.Tensor for a PyTorch argument, a
/// cupy.ndarray for a CuPy one, else a nanobind array-API object that any DLPack consumer imports).
struct DeviceOut {
  nb::object object;
  double* data = nullptr;
  std::size_t size = 0;
};
DeviceOut device_output(nb::handle out, const std::vector<std::size_t>& shape, const std::string& where,
                        nb::handle like, const DeviceIn* input = nullptr);

/// A read-only (size / 3, 3) view of `size` doubles at `data` in host memory (device < 0) or on
/// CUDA device `device`, with no copy, as an array-API object (__dlpack__, __dlpack_device__) that
/// NumPy, CuPy and PyTorch import by from_dlpack; it keeps `owner` alive. Versioned DLPack exports
/// (DLPack 1.0) carry the read-only flag; the unversioned protocol has none (docs/python.md,
/// "Device arrays").
nb::object read_only_view(const double* data, std::size_t size, int device, nb::handle owner);

/// Waits for all work queued on the current device (any stream); rpyfmm::Error on a CUDA error.
void synchronize_device(const std::string& where);

/// rpyfmm.cuda.to_device and to_host (device_arrays.cpp).
void bind_device_arrays(nb::module_& m);

/// Products of the CUDA PSE operator on device arrays (pse_cuda.cpp), reached from
/// MobilityOperator.set_positions and .apply when an argument is a device array: `op` must be a
/// PseRpyCuda (else the refusal above).
void set_positions_on_device(rpy::MobilityOperator& op, nb::handle positions, RadiusArg radius);
nb::object apply_on_device(const rpy::MobilityOperator& op, nb::handle forces, nb::handle torques, nb::handle out);

/// The PseRpyCuda class (pse_cuda.cpp).
void bind_pse_cuda(nb::module_& m);

}  // namespace rpyfmm::python
