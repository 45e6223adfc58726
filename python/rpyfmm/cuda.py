"""rpyfmm.cuda — device arrays for the CUDA PSE operator (docs/python.md, "Device arrays").

:class:`rpyfmm.PseRpyCuda` reads and writes CUDA device arrays in place through DLPack: CuPy
arrays, PyTorch CUDA tensors, and the arrays :func:`to_device` returns (which CuPy's and
PyTorch's ``from_dlpack`` import without a copy). Results of a product on device arrays are
device arrays in the input's framework. :class:`rpyfmm.libmobility.PSE` with
``setParameters(..., device="cuda")`` takes CuPy and PyTorch arrays through it, and the device BD
engine gives its own arrays as views (``Simulation.device_positions()``, ``device_forces()``).
Every other call takes host (NumPy) arrays and refuses device arrays with an
:class:`rpyfmm.InvalidInputError` that names them.

* :func:`to_device` ``(array)``: a float64 copy of a host array on the current device.
* :func:`to_host` ``(array)``: a NumPy copy of a float64 C-contiguous CUDA array.

Both raise :class:`rpyfmm.NotSupportedError` in a build without CUDA or without a usable device
(:func:`rpyfmm.cuda_device_available`).
"""

from __future__ import annotations

from ._rpyfmm import cuda as _cuda

to_device = _cuda.to_device
to_host = _cuda.to_host

__all__ = ["to_device", "to_host"]
