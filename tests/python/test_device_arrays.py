"""Device arrays through DLPack (docs/python.md, "Device arrays").

Everywhere: a device array (anything whose __dlpack_device__ names a device other than the host)
passed to a call that takes host arrays raises InvalidInputError naming the argument and its
device, before any data is read; the CUDA operator and rpyfmm.cuda refuse clearly without a
usable device. On a GPU (rpyfmm.cuda_device_available()): PseRpyCuda's products on device arrays
(rpyfmm.cuda.to_device, CuPy, PyTorch, each where installed) equal its products on host arrays bit
for bit, since the device entry points run the same operations on the same vectors as the host
ones after their copies (the C++ tests PseCudaDeviceStep.* show the same for apply_with_noise and
set_positions); bad device inputs (NaN, shape, dtype, size) raise before the operator runs.

Simulation's device engine: device_positions() and device_forces() are read-only views of the
engine's own arrays, no copy, in the particle order given. On the host launcher (no GPU needed)
they are kDLCPU arrays equal bit for bit to positions and last_forces at every step, two views at
one step share their memory, and a view keeps the Simulation alive; the engine takes host
positions only. On the CUDA engine the same checks run on kDLCUDA arrays (rpyfmm.cuda.to_host
reads them)."""

from __future__ import annotations

import gc
import sys

import numpy as np
import pytest

import rpyfmm

GPU = rpyfmm.cuda_device_available()
needs_gpu = pytest.mark.skipif(not GPU, reason="no usable CUDA device")
NO_GPU = r"no usable CUDA device|without CUDA|no CUDA support"


class FakeDeviceArray:
    """Claims to live on a device; reading its data fails (no call may get that far)."""

    def __init__(self, device_type: int = 2, device_id: int = 0):
        self.device = (device_type, device_id)

    def __dlpack_device__(self):
        return self.device

    def __dlpack__(self, **kwargs):
        raise AssertionError("the data of a refused device array was read")

    def __array__(self, *args, **kwargs):
        # As CuPy arrays and CUDA tensors: no implicit conversion to NumPy.
        raise TypeError("implicit conversion of a device array to a NumPy array")


def positions(n: int = 64, box: float = 12.0, seed: int = 3) -> np.ndarray:
    return np.random.default_rng(seed).uniform(0.0, box, size=(n, 3))


@pytest.fixture
def direct() -> rpyfmm.DirectRpy:
    op = rpyfmm.DirectRpy()
    op.set_positions(positions(8, 20.0), 1.0)
    return op


@pytest.mark.parametrize("device", [(2, 0), (13, 1), (10, 0)])
def test_host_operators_refuse_device_arrays(direct, device):
    fake = FakeDeviceArray(*device)
    with pytest.raises(rpyfmm.InvalidInputError, match=r"apply: forces is a device array.*'direct' operator"):
        direct.apply(fake)
    with pytest.raises(rpyfmm.InvalidInputError, match=r"set_positions: positions is a device array"):
        direct.set_positions(fake, 1.0)
    with pytest.raises(rpyfmm.InvalidInputError, match=r"apply_sqrt: z is a .*:\d device array"):
        direct.apply_sqrt(fake)
    with pytest.raises(rpyfmm.InvalidInputError, match=r"out is a .* device array"):
        direct.apply(np.ones((8, 3)), out=fake)
    # The operator is untouched: the next product is the one before the refused calls.
    f = np.ones((8, 3))
    u = direct.apply(f)
    assert np.array_equal(direct.apply(f), u)


def test_other_calls_refuse_device_arrays():
    fake = FakeDeviceArray()
    with pytest.raises(rpyfmm.InvalidInputError, match=r"sources is a cuda:0 device array.*copy it to the host"):
        rpyfmm.LaplaceFmm().set_points(fake)
    pse = rpyfmm.PseRpy(box=12.0)
    pse.set_positions(positions(), 1.0)
    with pytest.raises(rpyfmm.InvalidInputError, match=r"forces is a device array.*'pse' operator runs on the CPU"):
        pse.apply(fake)
    with pytest.raises(rpyfmm.InvalidInputError, match=r"apply_with_noise: forces is a cuda:0 device array"):
        pse.apply_with_noise(fake, 1.0, seed=1)


def libmobility_solvers():
    from rpyfmm.libmobility import PSE, NBody, SelfMobility

    nbody, free, pse = NBody("open", "open", "open"), SelfMobility("open", "open", "open"), PSE(*["periodic"] * 3)
    nbody.setParameters()
    free.setParameters()
    pse.setParameters(psi=0.5, Lx=20.0, Ly=20.0, Lz=20.0)  # device="cpu": PseRpy
    return nbody, free, pse


@pytest.mark.parametrize("solver", libmobility_solvers(), ids=["NBody", "SelfMobility", "PSE"])
def test_libmobility_cpu_solvers_refuse_device_arrays(solver):
    solver.initialize(viscosity=1.0, hydrodynamicRadius=1.0)
    with pytest.raises(rpyfmm.InvalidInputError, match=r"positions is a device array \(DLPack device \(2, 0\)\)"):
        solver.setPositions(FakeDeviceArray())
    solver.setPositions(positions(8, 20.0))
    with pytest.raises(rpyfmm.InvalidInputError, match=r"Mdot: forces is a device array.*this solver takes host"):
        solver.Mdot(FakeDeviceArray())
    with pytest.raises(rpyfmm.InvalidInputError, match=r"LangevinVelocities: forces is a device array"):
        solver.LangevinVelocities(0.1, 1.0, forces=FakeDeviceArray())
    # The solver is untouched: host products go on.
    assert solver.Mdot(np.ones((8, 3)))[0].shape == (8, 3)


def test_host_arrays_with_dlpack_are_host_arrays(direct):
    # NumPy arrays have __dlpack_device__ too (kDLCPU): they take the host path, read in place.
    f = np.arange(24, dtype=np.float64).reshape(8, 3)
    assert f.__dlpack_device__()[0] == 1
    assert rpyfmm._rpyfmm._input_address(f) == f.ctypes.data
    assert np.array_equal(direct.apply(f), direct.apply(f.tolist()))


@pytest.mark.skipif(GPU, reason="a usable CUDA device is present")
def test_without_a_device_the_cuda_calls_say_why():
    with pytest.raises(rpyfmm.NotSupportedError, match=NO_GPU):
        rpyfmm.PseRpyCuda(box=10.0)
    with pytest.raises(rpyfmm.NotSupportedError, match=NO_GPU):
        rpyfmm.cuda.to_device(np.ones(3))
    with pytest.raises(rpyfmm.NotSupportedError, match=NO_GPU):
        rpyfmm.cuda.to_host(FakeDeviceArray())


def engine_simulation(**kw) -> rpyfmm.Simulation:
    """64 WCA spheres of radius 1 under a constant force on the device engine (free draining, or
    PSE with mobility='pse' and a box)."""
    grid = np.stack(np.meshgrid(*[np.arange(4)] * 3, indexing="ij"), axis=-1).reshape(-1, 3) * 2.5
    x = grid + np.random.default_rng(3).uniform(-0.05, 0.05, size=grid.shape)
    args = dict(dt=5e-3, seed=7, mobility="none", pair="wca", external_force=[0.3, 0.0, -0.5], device="cuda")
    args.update(kw)
    return rpyfmm.Simulation(x, 1.0, **args)


def host_view(view) -> np.ndarray:
    """The values of a device-engine view: NumPy reads a kDLCPU one in place, a kDLCUDA one is copied."""
    return np.from_dlpack(view) if view.__dlpack_device__()[0] == 1 else rpyfmm.cuda.to_host(view)


def expect_views_follow_the_steps(sim: rpyfmm.Simulation, steps: int) -> None:
    """A fresh view after each step equals positions / last_forces bit for bit."""
    for s in range(steps):
        sim.step()
        np.testing.assert_array_equal(host_view(sim.device_positions()), sim.positions, err_msg=f"step {s}")
        np.testing.assert_array_equal(host_view(sim.device_forces()), sim.last_forces, err_msg=f"step {s}")


@pytest.mark.parametrize("mobility", [{}, dict(mobility="pse", box=10.0, tolerance=1e-4)])
def test_device_engine_views_on_the_host_launcher(mobility):
    sim = engine_simulation(device_launcher="host", **mobility)
    view = sim.device_positions()
    assert view.__dlpack_device__() == (1, 0)
    x = np.from_dlpack(view)
    assert x.shape == (64, 3) and x.dtype == np.float64
    np.testing.assert_array_equal(x, sim.positions)  # the particle order given: no permutation
    assert not x.flags.writeable and not np.asarray(sim.device_forces()).flags.writeable
    with pytest.raises(ValueError, match="read-only"):
        x[0, 0] = 1.0
    # No copy: two views of one step share the engine's array.
    assert np.from_dlpack(sim.device_positions()).ctypes.data == x.ctypes.data
    expect_views_follow_the_steps(sim, 12)
    assert np.abs(sim.last_forces).max() > 0, "the forces must act"


def test_torch_imports_the_read_only_views_on_the_host_launcher():
    # The views carry DLPack 1.0's read-only flag; PyTorch imports them (it has no read-only
    # tensors, so the flag only tells it not to write), sharing the engine's memory.
    torch = pytest.importorskip("torch")
    sim = engine_simulation(device_launcher="host")
    sim.run(2)
    x = torch.from_dlpack(sim.device_positions())
    assert x.shape == (64, 3) and x.dtype == torch.float64 and x.device.type == "cpu"
    np.testing.assert_array_equal(x.numpy(), sim.positions)
    assert x.data_ptr() == np.from_dlpack(sim.device_positions()).ctypes.data
    np.testing.assert_array_equal(torch.from_dlpack(sim.device_forces()).numpy(), sim.last_forces)


def test_a_view_keeps_the_simulation_alive():
    sim = engine_simulation(device_launcher="host")
    sim.run(3)
    before = sys.getrefcount(sim)
    view, forces = sim.device_positions(), sim.device_forces()
    assert sys.getrefcount(sim) == before + 2  # each view holds a reference to the Simulation
    expected, expected_forces = np.array(sim.positions), np.array(sim.last_forces)
    del sim
    gc.collect()
    np.testing.assert_array_equal(np.from_dlpack(view), expected)
    np.testing.assert_array_equal(np.from_dlpack(forces), expected_forces)


def test_cpu_engine_offers_no_device_views():
    sim = engine_simulation(device="cpu")
    with pytest.raises(rpyfmm.NotSupportedError, match=r"device_positions: the 'cpu' engine.*Simulation.positions"):
        sim.device_positions()
    with pytest.raises(rpyfmm.NotSupportedError, match=r"device_forces: the 'cpu' engine"):
        sim.device_forces()


def test_device_engine_takes_host_positions_only():
    """The engine has no setter: its positions come from the constructor's host array."""
    with pytest.raises(rpyfmm.InvalidInputError, match=r"positions is a cuda:0 device array, but this call takes host"):
        rpyfmm.Simulation(FakeDeviceArray(), 1.0, dt=5e-3, mobility="none", device="cuda", device_launcher="host")


# ---- on a GPU -------------------------------------------------------------------------------


@needs_gpu
def test_device_engine_views_on_the_gpu():
    sim = engine_simulation()
    assert sim.engine == "cuda"
    assert sim.device_positions().__dlpack_device__()[0] == 2
    np.testing.assert_array_equal(host_view(sim.device_positions()), sim.positions)
    expect_views_follow_the_steps(sim, 12)
    for framework in ("cupy", "torch"):
        try:
            xp = __import__(framework)
        except ImportError:
            continue
        x = xp.from_dlpack(sim.device_positions())
        back = x.cpu().numpy() if framework == "torch" else xp.asnumpy(x)
        np.testing.assert_array_equal(back, sim.positions)



def cuda_operator(n: int = 300, box: float = 16.0) -> tuple[rpyfmm.PseRpyCuda, np.ndarray]:
    op = rpyfmm.PseRpyCuda(box=box, tolerance=1e-4)
    x = positions(n, box, seed=5)
    op.set_positions(x, 1.0)
    return op, x


@needs_gpu
def test_to_device_and_back_is_exact():
    a = np.random.default_rng(1).standard_normal((50, 3))
    d = rpyfmm.cuda.to_device(a)
    assert d.__dlpack_device__()[0] == 2
    assert np.array_equal(rpyfmm.cuda.to_host(d), a)


@needs_gpu
def test_device_products_are_the_host_products():
    op, _ = cuda_operator()
    rng = np.random.default_rng(2)
    f, t = rng.standard_normal((2, op.size, 3))
    u = op.apply(f)
    ud = op.apply(rpyfmm.cuda.to_device(f))
    assert np.array_equal(rpyfmm.cuda.to_host(ud), u)
    uw = op.apply(f, t)
    uwd = op.apply(rpyfmm.cuda.to_device(f), rpyfmm.cuda.to_device(t))
    for host, device in zip(uw, uwd):
        assert np.array_equal(rpyfmm.cuda.to_host(device), host)
    noisy, report = op.apply_with_noise(f, 0.7, seed=9, step=4)
    noisy_d, report_d = op.apply_with_noise(rpyfmm.cuda.to_device(f), 0.7, seed=9, step=4)
    assert np.array_equal(rpyfmm.cuda.to_host(noisy_d), noisy)
    assert report_d.iterations == report.iterations
    w, _ = op.sample(seed=9, step=4)
    out = rpyfmm.cuda.to_device(np.zeros((op.size, 3)))
    w_d, _ = op.sample(seed=9, step=4, out=out)
    assert w_d is out
    assert np.array_equal(rpyfmm.cuda.to_host(out), w)


@needs_gpu
def test_device_positions_move_the_particles():
    op, x = cuda_operator()
    moved = x + np.random.default_rng(4).uniform(-0.2, 0.2, size=x.shape)
    f = np.random.default_rng(6).standard_normal(x.shape)
    op.set_positions(rpyfmm.cuda.to_device(moved), 1.0)
    u_device_positions = op.apply(f)
    host, _ = cuda_operator()
    host.set_positions(moved, 1.0)
    assert np.array_equal(u_device_positions, host.apply(f))
    with pytest.raises(rpyfmm.InvalidInputError, match=r"same N, same radius"):
        op.set_positions(rpyfmm.cuda.to_device(moved), 1.5)


@needs_gpu
def test_bad_device_inputs_are_refused():
    op, _ = cuda_operator()
    f = np.ones((op.size, 3))
    f[7, 1] = np.nan
    with pytest.raises(rpyfmm.InvalidInputError, match=r"forces contains NaN or Inf"):
        op.apply(rpyfmm.cuda.to_device(f))
    with pytest.raises(rpyfmm.InvalidInputError, match=r"forces holds 10 particles, the operator 300"):
        op.apply(rpyfmm.cuda.to_device(np.ones((10, 3))))
    with pytest.raises(rpyfmm.InvalidInputError, match=r"forces has shape \(300, 2\)"):
        op.apply(rpyfmm.cuda.to_device(np.ones((300, 2))))
    d = rpyfmm.cuda.to_device(np.ones((op.size, 3)))
    with pytest.raises(rpyfmm.InvalidInputError, match=r"out must not share memory"):
        op.apply(d, out=d)


@needs_gpu
@pytest.mark.parametrize("framework", ["cupy", "torch"])
def test_framework_arrays_in_and_out(framework):
    xp = pytest.importorskip(framework)
    op, _ = cuda_operator()
    f = np.random.default_rng(8).standard_normal((op.size, 3))
    fd = xp.asarray(f, device="cuda") if framework == "torch" else xp.asarray(f)
    u = op.apply(fd)
    assert type(u) is type(fd)
    back = u.cpu().numpy() if framework == "torch" else xp.asnumpy(u)
    assert np.array_equal(back, op.apply(f))
    with pytest.raises(rpyfmm.InvalidInputError, match=r"float64 C-contiguous CUDA array"):
        op.apply(fd.float() if framework == "torch" else fd.astype(xp.float32))
