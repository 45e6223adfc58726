"""The device BD engine behind Simulation (docs/gpu-bd.md): device='cuda' with mobility 'none'
(or 'pse' in a periodic box) selects it, device_launcher='host' runs its stages on the CPU, where its trajectory is the CPU
engine's bit for bit (x86-64 builds, which do not fuse multiply-adds); from_config takes it from
[mobility] device = "cuda"; a Python force callback is refused there by name; and without a
usable GPU device='cuda' raises, saying why."""

from __future__ import annotations

import platform

import numpy as np
import pytest

import rpyfmm

# x86-64 builds keep a * b + c unfused (no -march=native): launcher and CPU engine agree bit for
# bit. Elsewhere (AArch64 fuses) they agree to 1e-12 (step + 1) max|x| over the first 10 steps.
BITWISE = platform.machine() in ("x86_64", "AMD64")
NO_GPU = r"no usable CUDA device|no CUDA support"


def lattice(side: int, spacing: float, jitter: float, seed: int) -> np.ndarray:
    """(side^3, 3) points of a cubic lattice, each moved by up to +-jitter per coordinate."""
    rng = np.random.default_rng(seed)
    grid = np.stack(np.meshgrid(*[np.arange(side)] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    return grid * spacing + rng.uniform(-jitter, jitter, size=grid.shape)


def simulation(**kw) -> rpyfmm.Simulation:
    """125 WCA spheres of radius 1 under a constant force, free draining, free space."""
    args = dict(radius=1.0, dt=5e-3, seed=7, mobility="none", viscosity=0.8, pair="wca", external_force=[0.3, 0.0, -0.5])
    args.update(kw)
    return rpyfmm.Simulation(lattice(5, 2.4, 0.05, 3), **args)


def expect_same_steps(dev: rpyfmm.Simulation, cpu: rpyfmm.Simulation, steps: int) -> None:
    """Steps both, comparing positions, forces and reports after each."""
    scale = max(1.0, float(np.abs(cpu.positions).max()))
    for s in range(steps if BITWISE else min(steps, 10)):
        a, b = dev.step(), cpu.step()
        if BITWISE:
            np.testing.assert_array_equal(dev.positions, cpu.positions, err_msg=f"step {s}")
            np.testing.assert_array_equal(dev.last_forces, cpu.last_forces, err_msg=f"step {s}")
            assert a.potential_energy == b.potential_energy
        else:
            np.testing.assert_allclose(dev.positions, cpu.positions, rtol=0, atol=1e-12 * scale * (s + 1))
        assert a.neighbour_rebuild == b.neighbour_rebuild and a.mobility_products == b.mobility_products
    assert dev.step_count == cpu.step_count and dev.neighbour_rebuilds == cpu.neighbour_rebuilds


def test_host_launcher_steps_as_the_cpu_engine():
    dev = simulation(device="cuda", device_launcher="host")
    cpu = simulation()
    assert dev.engine == "host launcher" and cpu.engine == "cpu" and dev.mobility == "none"
    view = dev.positions
    expect_same_steps(dev, cpu, 60)
    assert dev.neighbour_rebuilds >= 2, "the run must rebuild its lists"
    dev.run(5)
    cpu.run(5)
    if BITWISE:  # the view, not read again, is live on the device engine too
        np.testing.assert_array_equal(view, cpu.positions)
    totals = dev.totals()
    assert totals["steps"] == 65 and totals["mobility_products"] == cpu.totals()["mobility_products"]
    assert totals["seconds"]["forces"] > 0 and totals["seconds"]["sqrt"] == 0


def test_pse_on_the_host_launcher_steps_as_the_cpu_engine():
    """mobility 'pse' in a periodic box: the device engine's PSE stage (docs/gpu-bd.md, "PSE on
    the device") on the host launcher makes the CPU engine's PSE calls, bit for bit."""
    args = dict(mobility="pse", box=5 * 2.4, tolerance=1e-4, external_force=[0.0, 0.0, 0.0])
    dev = simulation(device="cuda", device_launcher="host", **args)
    cpu = simulation(**args)
    assert dev.engine == "host launcher" and cpu.engine == "cpu" and dev.mobility == "pse"
    expect_same_steps(dev, cpu, 25)
    assert dev.last_report.sqrt_iterations == cpu.last_report.sqrt_iterations > 0
    assert dev.totals()["seconds"]["drift"] > 0


DEVICE_CONFIG = """
# 216 soft spheres on a lattice in a trap, free draining on the device engine
[[types]]
name = "A"
radius = 0.5
[particles]
source = "lattice"
count = 216
volume_fraction = 0.3
[[pair]]
types = ["A", "A"]
kind = "soft"
epsilon = 20.0
sigma = 1.3
[external]
trap_stiffness = 0.05
[integrator]
dt = 2e-3
seed = 12
steps = 30
[neighbours]
skin = 0.1
[mobility]
method = "none"
device = "cuda"
"""


def test_from_config_takes_the_device_engine_from_the_config():
    dev = rpyfmm.Simulation.from_config(DEVICE_CONFIG, device_launcher="host")
    cpu = rpyfmm.Simulation.from_config(DEVICE_CONFIG.replace('device = "cuda"', 'device = "cpu"'))
    assert dev.engine == "host launcher" and cpu.engine == "cpu"
    expect_same_steps(dev, cpu, 30)
    assert dev.neighbour_rebuilds >= 2, "the run must rebuild its lists"
    assert dev.last_report.potential_energy > 0, "the soft spheres must interact"


def test_python_force_refused_on_the_device_engine():
    def force(x, step, f):
        f[:, 2] -= 1.0

    with pytest.raises(rpyfmm.NotSupportedError, match=r"Python force callback.*device='cpu'"):
        simulation(device="cuda", device_launcher="host", force=force)
    with pytest.raises(rpyfmm.NotSupportedError, match="Python force callback"):
        rpyfmm.Simulation.from_config(DEVICE_CONFIG, force=force, device_launcher="host")
    assert simulation(force=force).engine == "cpu"  # the CPU engine calls it
    with pytest.raises(rpyfmm.Error, match="unknown device_launcher 'gpu'"):
        simulation(device="cuda", device_launcher="gpu")


def test_features_the_device_engine_lacks_refused_by_name():
    rotating = DEVICE_CONFIG.replace("[[types]]", "[system]\nrotation = true\n[[types]]", 1)
    with pytest.raises(rpyfmm.NotSupportedError, match="rotation"):
        rpyfmm.Simulation.from_config(rotating, device_launcher="host")


def test_cuda_without_a_gpu_says_why(tmp_path):
    if rpyfmm.cuda_device_available():
        cuda = simulation(device="cuda")
        assert cuda.engine == "cuda"
        expect_same_steps(cuda, simulation(device="cuda", device_launcher="host"), 20)
        return
    with pytest.raises(rpyfmm.NotSupportedError, match=NO_GPU):
        simulation(device="cuda")
    with pytest.raises(rpyfmm.NotSupportedError, match=NO_GPU):
        rpyfmm.Simulation.from_config(DEVICE_CONFIG)
    with pytest.raises(rpyfmm.NotSupportedError, match=NO_GPU):
        rpyfmm.run_bd(DEVICE_CONFIG, out_dir=str(tmp_path / "run"))
    assert not (tmp_path / "run").exists()
