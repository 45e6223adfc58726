"""rpyfmm.libmobility with device arrays (docs/python.md, "Device arrays").

Everywhere: PSE with setParameters(..., device="cuda") asks for rpyfmm.PseRpyCuda and, without a
usable GPU, initialize says why; the CPU solvers refuse device arrays (test_device_arrays.py).

Without a GPU, the CUDA solver's Python path is checked against a stand-in: PseRpy behind
PseRpyCuda's interface (device arrays in, device arrays out) and host arrays that claim to live on
cuda:0 in a stand-in "cupy" module. A solver fed the stand-in device arrays then gives the bits of
one fed host arrays, call after call (routing, zeros for missing forces, noise counter and scaling,
shapes, the framework of the results): both reach the same PseRpy products in the same order.

On a GPU, the real CUDA solver fed CuPy or PyTorch arrays gives the bits of the same solver fed
NumPy arrays: PseRpyCuda's device entry points run the same operations as its host ones
(test_device_arrays.py), and the solver's arithmetic (u += s * w) is the same IEEE operations in
every framework."""

from __future__ import annotations

import sys
import types

import numpy as np
import pytest

import rpyfmm
import rpyfmm.libmobility as libmobility
from conftest import suspension
from rpyfmm.libmobility import PSE

GPU = rpyfmm.cuda_device_available()
NO_GPU = r"no usable CUDA device|without CUDA|no CUDA support"
ETA, A, BOX = 1.3, 0.9, (16.0, 17.0, 18.0)


def pse(device: str = "cpu", angular: bool = False, **init) -> PSE:
    solver = PSE("periodic", "periodic", "periodic")
    solver.setParameters(psi=0.5, Lx=BOX[0], Ly=BOX[1], Lz=BOX[2], device=device)
    solver.initialize(viscosity=ETA, hydrodynamicRadius=A, includeAngular=angular, tolerance=1e-4, seed=9, **init)
    return solver


@pytest.fixture(scope="module")
def system() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(21)
    x = suspension(60, radius=A, spacing=2.2, seed=4) % BOX[0]
    return x, rng.standard_normal(x.shape), rng.standard_normal(x.shape)


def test_cuda_device_is_asked_for_by_name():
    solver = PSE("periodic", "periodic", "periodic")
    with pytest.raises(rpyfmm.InvalidArgumentError, match=r"device = 'gpu', expected 'cpu' or 'cuda'"):
        solver.setParameters(psi=0.5, Lx=10.0, Ly=10.0, Lz=10.0, device="gpu")
    if GPU:
        assert isinstance(pse("cuda")._op, rpyfmm.PseRpyCuda)
    else:
        with pytest.raises(rpyfmm.NotSupportedError, match=NO_GPU):
            pse("cuda")


# ---- the CUDA solver's Python path, on a stand-in operator ----------------------------------


class StandInArray:
    """A host array claiming to live on cuda:0, of a stand-in "cupy" module."""

    __module__ = "cupy"

    def __init__(self, a: np.ndarray):
        self.a = np.array(a, dtype=np.float64)

    def __dlpack_device__(self):
        return (2, 0)

    @property
    def shape(self):
        return self.a.shape

    def __iadd__(self, other: "StandInArray") -> "StandInArray":
        self.a += other.a
        return self

    def __imul__(self, c: float) -> "StandInArray":
        self.a *= c
        return self


def host(a):
    return a.a if isinstance(a, StandInArray) else a


class StandInCudaOperator:
    """PseRpy behind PseRpyCuda's interface: stand-in device arrays are read and written through."""

    def __init__(self, op: rpyfmm.PseRpy):
        self.op = op
        self.device_calls = 0

    def __getattr__(self, name: str):
        return getattr(self.op, name)

    def set_positions(self, x, a: float) -> None:
        self.device_calls += isinstance(x, StandInArray)
        self.op.set_positions(host(x), a)

    def apply(self, f, t=None):
        on_device = isinstance(f, StandInArray)
        self.device_calls += on_device
        r = self.op.apply(host(f)) if t is None else self.op.apply(host(f), host(t))
        wrap = StandInArray if on_device else (lambda v: v)
        return wrap(r.reshape(host(f).shape)) if t is None else tuple(wrap(v.reshape(host(f).shape)) for v in r)

    def sample(self, seed: int, step: int, out=None):
        w, report = self.op.sample(seed, step)
        if out is None:
            return w, report
        self.device_calls += 1
        out.a[...] = w.reshape(out.a.shape)
        return out, report


@pytest.fixture
def stand_in(monkeypatch):
    """Makes PSE solvers whose operator is the stand-in, as PSE(device='cuda') is set up."""
    module = types.ModuleType("cupy")
    module.zeros_like = lambda x: StandInArray(np.zeros_like(x.a))
    monkeypatch.setitem(sys.modules, "cupy", module)
    monkeypatch.setattr(libmobility, "cuda", types.SimpleNamespace(to_host=lambda x: x.a.copy()))

    def make(angular: bool = False, **init) -> PSE:
        solver = pse(angular=angular, **init)
        solver._op = StandInCudaOperator(solver._op)
        solver._device_arrays = True
        return solver

    return make


def same(device_result, host_result) -> None:
    assert isinstance(device_result, StandInArray)
    assert device_result.shape == host_result.shape
    np.testing.assert_array_equal(device_result.a, host_result)


def test_device_arrays_take_the_host_paths_products(stand_in, system):
    x, f, _ = system
    on_device, on_host = stand_in(), stand_in()
    moved = (x + 0.1) % BOX[0]
    for positions, shape in ((x, x.shape), (moved.ravel(), (3 * len(x),))):
        on_device.setPositions(StandInArray(positions))
        on_host.setPositions(positions)
        force = f.reshape(shape)
        same(on_device.Mdot(StandInArray(force))[0], on_host.Mdot(force)[0])
        same(on_device.sqrtMdotW(0.7)[0], on_host.sqrtMdotW(0.7)[0])
        same(on_device.LangevinVelocities(0.01, 0.3, forces=StandInArray(force))[0],
             on_host.LangevinVelocities(0.01, 0.3, forces=force)[0])
        same(on_device.LangevinVelocities(0.01, 0.3)[0], on_host.LangevinVelocities(0.01, 0.3)[0])
        same(on_device.divM()[0], on_host.divM()[0])
    # The first setPositions builds the plan from a host copy, the second moves it on the device;
    # per round two products M F (Mdot, LangevinVelocities) and three samples ran on the device.
    assert on_device._op.device_calls == 1 + 2 * 5
    assert on_host._op.device_calls == 0
    # libMobility before 0.9: hydrodynamicVelocities(F, T, prefactor) with initialize(temperature=kT).
    earlier_device, earlier_host = stand_in(temperature=2.0), stand_in(temperature=2.0)
    earlier_device.setPositions(StandInArray(x))
    earlier_host.setPositions(x)
    same(earlier_device.hydrodynamicVelocities(StandInArray(f), None, 0.5)[0],
         earlier_host.hydrodynamicVelocities(f, None, 0.5)[0])
    # The CUDA solver's noise is its operator's sampler keyed by (seed, call): call 0 here.
    reference = pse()._op
    reference.set_positions(x, A)
    fresh = stand_in()
    fresh.setPositions(StandInArray(x))
    same(fresh.sqrtMdotW(0.7)[0], 0.7 * reference.sample(9, 0)[0])


def test_device_torques_and_what_is_refused(stand_in, system):
    x, f, t = system
    on_device, on_host = stand_in(angular=True), stand_in(angular=True)
    on_device.setPositions(StandInArray(x))
    on_host.setPositions(x)
    for args in ((f, t), (None, t), (f, None)):
        device_args = [None if a is None else StandInArray(a) for a in args]
        for d, h in zip(on_device.Mdot(*device_args), on_host.Mdot(*args)):
            same(d, h)
    with pytest.raises(rpyfmm.NotSupportedError, match=r"sqrtMdotW: with includeAngular=True the noise takes host"):
        on_device.sqrtMdotW()
    with pytest.raises(rpyfmm.InvalidInputError, match=r"forces and torques must be all device arrays or all host"):
        on_device.Mdot(f, StandInArray(t))
    plain = stand_in()
    plain.setPositions(StandInArray(x))
    with pytest.raises(rpyfmm.InvalidArgumentError, match=r"torques given but .*includeAngular=False"):
        plain.Mdot(StandInArray(f), StandInArray(t))
    with pytest.raises(rpyfmm.InvalidInputError, match=r"device array of type .*CuPy arrays and PyTorch tensors"):
        plain.Mdot(types.SimpleNamespace(__dlpack_device__=lambda: (2, 0)))


# ---- on a GPU -------------------------------------------------------------------------------


@pytest.mark.skipif(not GPU, reason="no usable CUDA device")
@pytest.mark.parametrize("framework", ["cupy", "torch"])
def test_cuda_solver_on_device_arrays_is_the_host_products(framework, system):
    xp = pytest.importorskip(framework)

    def to(a: np.ndarray):
        return xp.asarray(a, device="cuda") if framework == "torch" else xp.asarray(a)

    def back(a) -> np.ndarray:
        return a.cpu().numpy() if framework == "torch" else xp.asnumpy(a)

    x, f, _ = system
    on_device, on_host = pse("cuda"), pse("cuda")
    moved = (x + 0.1) % BOX[0]
    for positions in (x, moved):
        on_device.setPositions(to(positions))
        on_host.setPositions(positions)
        u = on_device.Mdot(to(f))[0]
        assert type(u) is type(to(f))
        np.testing.assert_array_equal(back(u), on_host.Mdot(f)[0])
        np.testing.assert_array_equal(back(on_device.sqrtMdotW(0.7)[0]), on_host.sqrtMdotW(0.7)[0])
        dt, kbt = 0.01, 0.3
        np.testing.assert_array_equal(back(on_device.LangevinVelocities(dt, kbt, forces=to(f))[0]),
                                      on_host.LangevinVelocities(dt, kbt, forces=f)[0])
        np.testing.assert_array_equal(back(on_device.LangevinVelocities(dt, kbt)[0]),
                                      on_host.LangevinVelocities(dt, kbt)[0])
        np.testing.assert_array_equal(back(on_device.divM()[0]), on_host.divM()[0])
    earlier_device, earlier_host = pse("cuda", temperature=2.0), pse("cuda", temperature=2.0)
    earlier_device.setPositions(to(x))
    earlier_host.setPositions(x)
    np.testing.assert_array_equal(back(earlier_device.hydrodynamicVelocities(to(f), None, 0.5)[0]),
                                  earlier_host.hydrodynamicVelocities(f, None, 0.5)[0])
