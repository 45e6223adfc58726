// rpyfmm Python bindings — device arrays through DLPack (see device_arrays.hpp).
#include "device_arrays.hpp"

#include <algorithm>
#include <cstdint>
#include <functional>
#include <numeric>

#ifdef RPYFMM_HAVE_CUDA_PSE
#include <cuda_runtime.h>
#endif

namespace rpyfmm::python {
namespace {

using CudaView = nb::ndarray<const double, nb::c_contig, nb::device::cuda>;
using CudaWritable = nb::ndarray<double, nb::c_contig, nb::device::cuda>;

constexpr int kDLCPU = 1;
constexpr int kDLCUDA = 2;

std::size_t product(const std::vector<std::size_t>& shape) {
  return std::accumulate(shape.begin(), shape.end(), std::size_t{1}, std::multiplies<>());
}

template <class View>
std::vector<std::size_t> shape_of(const View& v) {
  std::vector<std::size_t> shape(v.ndim());
  for (std::size_t d = 0; d < v.ndim(); ++d) shape[d] = v.shape(d);
  return shape;
}

/// True for NumPy arrays (host memory), by one type check: the products' fast path.
bool is_numpy_array(nb::handle obj) {
  // numpy.ndarray, looked up once with the GIL held and kept for the module's lifetime.
  static PyObject* const ndarray = nb::object(nb::module_::import_("numpy").attr("ndarray")).release().ptr();
  return PyObject_TypeCheck(obj.ptr(), reinterpret_cast<PyTypeObject*>(ndarray)) != 0;
}

/// The module name of obj's type ("torch", "cupy", "numpy", ...), its first component.
std::string framework_of(nb::handle obj) {
  nb::handle type(reinterpret_cast<PyObject*>(Py_TYPE(obj.ptr())));
  if (!nb::hasattr(type, "__module__")) return {};
  const std::string module = nb::cast<std::string>(nb::str(type.attr("__module__")));
  return module.substr(0, module.find('.'));
}

#ifdef RPYFMM_HAVE_CUDA_PSE
void check_cuda(cudaError_t status, const std::string& where, const char* call) {
  if (status != cudaSuccess)
    fail(ErrorCode::numerical_failure, where, std::string(call) + " failed: " + cudaGetErrorString(status));
}

int current_device(const std::string& where) {
  int device = -1;
  const cudaError_t status = cudaGetDevice(&device);
  if (status != cudaSuccess)
    fail(ErrorCode::not_supported, where, std::string("no usable CUDA device: ") + cudaGetErrorString(status));
  return device;
}

/// 3N doubles (at least one) on the current device, freed with the returned capsule.
std::pair<double*, nb::capsule> allocate_device(std::size_t size, const std::string& where) {
  (void)current_device(where);  // a clear refusal without a usable device
  void* data = nullptr;
  const std::size_t bytes = std::max<std::size_t>(size, 1) * sizeof(double);
  const cudaError_t status = cudaMalloc(&data, bytes);
  if (status == cudaErrorMemoryAllocation)
    fail(ErrorCode::out_of_memory, where, "cudaMalloc of " + std::to_string(bytes) + " bytes failed");
  check_cuda(status, where, "cudaMalloc");
  nb::capsule owner(data, [](void* p) noexcept { cudaFree(p); });
  return {static_cast<double*>(data), std::move(owner)};
}
#else
[[noreturn]] void no_cuda(const std::string& where) {
  fail(ErrorCode::not_supported, where,
       "device arrays need a build with CUDA (this rpyfmm was built without CUDA; rpyfmm.cuda_device_available())");
}
#endif

/// A new device array of `shape` wrapping `data` (owned by `owner`), in like's framework.
nb::object wrap_device(double* data, const std::vector<std::size_t>& shape, const nb::capsule& owner, int device,
                       nb::handle like) {
  const std::string framework = framework_of(like);
  const auto make = [&]<class Framework>(Framework) {
    return nb::cast(nb::ndarray<Framework, double, nb::device::cuda>(data, shape.size(), shape.data(), owner, nullptr,
                                                                     nb::dtype<double>(), kDLCUDA, device));
  };
  if (framework == "torch") return make(nb::pytorch{});
  if (framework == "cupy") return make(nb::cupy{});
  return make(nb::array_api{});  // an object with __dlpack__ and __dlpack_device__ (a bare capsule has neither)
}

}  // namespace

DeviceIn device_input(nb::handle obj, const std::string& where, const std::string& name) {
  const std::optional<DlpackDevice> device = device_of(obj);
  if (!device)
    fail(ErrorCode::invalid_input, where,
         name + " is not a device array (its device is the host): pass host and device arrays as the call takes them");
  if (device->type != kDLCUDA)
    fail(ErrorCode::invalid_input, where,
         name + " is a " + device_name(*device) + " array; the CUDA operator takes CUDA device arrays (cuda:i)");
#ifdef RPYFMM_HAVE_CUDA_PSE
  const int current = current_device(where);
  if (device->id != current)
    fail(ErrorCode::invalid_input, where,
         name + " is on " + device_name(*device) + " but the operator runs on cuda:" + std::to_string(current) +
             " (the current device)");
  CudaView view;
  if (!nb::try_cast(obj, view, /*convert=*/false))
    fail(ErrorCode::invalid_input, where,
         name +
             " must be a float64 C-contiguous CUDA array (e.g. cupy.ascontiguousarray(x, dtype=cupy.float64), "
             "x.contiguous().double())");
  DeviceIn in;
  in.owner = nb::borrow(obj);
  in.data = view.data();
  in.shape = shape_of(view);
  in.size = product(in.shape);
  return in;
#else
  no_cuda(where);
#endif
}

std::optional<DlpackDevice> device_of(nb::handle obj) {
  if (obj.is_none() || is_numpy_array(obj) || !nb::hasattr(obj, "__dlpack_device__")) return std::nullopt;
  DlpackDevice device;
  try {
    const nb::tuple d = nb::cast<nb::tuple>(obj.attr("__dlpack_device__")());
    if (d.size() != 2) return std::nullopt;  // not (type, id); d[i] checks no bounds
    device.type = nb::cast<int>(d[0]);
    device.id = nb::cast<int>(d[1]);
  } catch (const std::exception&) {
    return std::nullopt;  // not a DLPack device: the array's own reading will report the problem
  }
  if (device.type == kDLCPU) return std::nullopt;
  return device;
}

std::string device_name(const DlpackDevice& device) {
  const std::string id = ":" + std::to_string(device.id);
  switch (device.type) {
    case kDLCUDA:
      return "cuda" + id;
    case 3:
      return "cuda_host" + id;
    case 10:
      return "rocm" + id;
    case 13:
      return "cuda_managed" + id;
    default:
      return "device type " + std::to_string(device.type) + id;
  }
}

std::string device_array_refusal(const std::string& name, const DlpackDevice& device) {
  return name + " is a " + device_name(device) +
         " device array, but this call takes host arrays: copy it to the host first (cupy.asnumpy(x), "
         "x.cpu().numpy(), rpyfmm.cuda.to_host(x)); device arrays are read in place by the CUDA PSE operator "
         "(rpyfmm.PseRpyCuda, make_mobility(..., device='cuda'))";
}

DeviceOut device_output(nb::handle out, const std::vector<std::size_t>& shape, const std::string& where,
                        nb::handle like, const DeviceIn* input) {
#ifdef RPYFMM_HAVE_CUDA_PSE
  DeviceOut result;
  result.size = product(shape);
  const int device = current_device(where);
  if (out.is_none()) {
    auto [data, owner] = allocate_device(result.size, where);
    result.data = data;
    result.object = wrap_device(data, shape, owner, device, like);
    return result;
  }
  const std::optional<DlpackDevice> d = device_of(out);
  CudaWritable view;
  if (!d || d->type != kDLCUDA || d->id != device || !nb::try_cast(out, view, /*convert=*/false))
    fail(ErrorCode::invalid_input, where,
         "out must be a writable float64 C-contiguous CUDA array on cuda:" + std::to_string(device) +
             " when the inputs are device arrays");
  if (product(shape_of(view)) != result.size)
    fail(ErrorCode::invalid_input, where,
         "out has shape " + shape_string(shape_of(view)) + ", expected " + shape_string(shape));
  result.data = view.data();
  if (input != nullptr && input->size > 0 && result.size > 0) {
    const auto in_lo = reinterpret_cast<std::uintptr_t>(input->data);
    const auto out_lo = reinterpret_cast<std::uintptr_t>(result.data);
    if (in_lo < out_lo + 8 * result.size && out_lo < in_lo + 8 * input->size)
      fail(ErrorCode::invalid_input, where, "out must not share memory with the input array");
  }
  result.object = nb::borrow(out);
  return result;
#else
  (void)out, (void)shape, (void)like, (void)input;
  no_cuda(where);
#endif
}

nb::object read_only_view(const double* data, std::size_t size, int device, nb::handle owner) {
  const std::size_t shape[2] = {size / 3, 3};
  const bool host = device < 0;
  return nb::cast(nb::ndarray<nb::array_api, const double>(data, 2, shape, owner, nullptr, nb::dtype<double>(),
                                                           host ? kDLCPU : kDLCUDA, host ? 0 : device),
                  nb::rv_policy::reference);
}

void synchronize_device(const std::string& where) {
#ifdef RPYFMM_HAVE_CUDA_PSE
  check_cuda(cudaDeviceSynchronize(), where, "cudaDeviceSynchronize");
#else
  no_cuda(where);
#endif
}

void bind_device_arrays(nb::module_& m) {
  nb::module_ cuda = m.def_submodule("cuda", "Device arrays for the CUDA PSE operator (docs/python.md).");
  cuda.def(
      "to_device",
      [](ArrayArg host) {
        const std::string where = "cuda.to_device";
        const InArray a = as_input(host, where, "array");
#ifdef RPYFMM_HAVE_CUDA_PSE
        auto [data, owner] = allocate_device(a.size, where);
        check_cuda(cudaMemcpy(data, a.data, a.size * sizeof(double), cudaMemcpyHostToDevice), where, "cudaMemcpy");
        return wrap_device(data, a.shape, owner, current_device(where), nb::none());
#else
        (void)a;
        no_cuda(where);
#endif
      },
      nb::arg("array"),
      "A float64 copy of a host array on the current CUDA device, as an array that CuPy, PyTorch\n"
      "(from_dlpack) and the CUDA PSE operator read in place. NotSupportedError in a build without CUDA.");
  cuda.def(
      "to_host",
      [](nb::handle device_array) {
        const std::string where = "cuda.to_host";
        const DeviceIn in = device_input(device_array, where, "array");
#ifdef RPYFMM_HAVE_CUDA_PSE
        synchronize_device(where);
        std::vector<double> host(in.size);
        check_cuda(cudaMemcpy(host.data(), in.data, in.size * sizeof(double), cudaMemcpyDeviceToHost), where,
                   "cudaMemcpy");
        return adopt_vector(std::move(host), in.shape).o;
#else
        (void)in;
        no_cuda(where);
#endif
      },
      nb::arg("array"), "A NumPy copy of a float64 C-contiguous CUDA array on the current device.");
}

}  // namespace rpyfmm::python
