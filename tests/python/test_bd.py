"""Brownian dynamics from Python: run_bd equals `rpyfmm bd` on the same config,
a stepped Simulation reproduces run_bd, Python force callbacks (exact drift,
exceptions, state kept), live position views."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

import rpyfmm

CONFIG = """
[system]
viscosity = 1.0
kT = 1.0
[[types]]
name = "A"
radius = 1.0
[particles]
source = "random"
count = 30
volume_fraction = 0.05
seed = 4
[[pair]]
types = ["A", "A"]
kind = "wca"
epsilon = 1.0
[integrator]
dt = 0.002
seed = 9
steps = 20
[mobility]
method = "direct"
[output]
dir = "bd-out"
trajectory_every = 5
log_every = 5
checkpoint_every = 0
"""


def test_run_bd_equals_cli(cli, tmp_path: Path):
    cfg = tmp_path / "run.toml"
    cfg.write_text(CONFIG)
    cli("bd", "--config", cfg, "--out-dir", tmp_path / "cli", "--quiet")
    summary = rpyfmm.run_bd(CONFIG, out_dir=str(tmp_path / "py"))
    assert summary["particles"] == 30 and summary["mobility"] == "direct" and summary["last_step"] == 20
    assert summary["engine"] == "cpu"
    assert (tmp_path / "py" / "trajectory.xyz").read_bytes() == (tmp_path / "cli" / "trajectory.xyz").read_bytes()
    # A path and a RunConfig work too.
    config = rpyfmm.load_config(cfg)
    assert config.steps == 20 and config.dt == 0.002 and config.mobility == "direct"
    s2 = rpyfmm.run_bd(config, steps=10, out_dir=str(tmp_path / "py2"))
    assert s2["last_step"] == 10


def test_simulation_reproduces_run_bd(tmp_path: Path):
    rpyfmm.run_bd(CONFIG, out_dir=str(tmp_path))
    _, steps, frames = rpyfmm.read_xyz(tmp_path / "trajectory.xyz")
    sim = rpyfmm.Simulation.from_config(CONFIG)
    assert sim.size == 30 and sim.mobility == "direct"
    for k in range(1, 5):
        sim.run(5)
        assert sim.step_count == steps[k]
        np.testing.assert_allclose(sim.positions, frames[k], rtol=1e-9, atol=1e-9)  # XYZ keeps 10 digits
    assert sim.totals()["steps"] == 20


ROTATING = """
[system]
rotation = true
[[types]]
name = "A"
dipole = 2.0
[particles]
source = "lattice"
count = 27
[external]
dipole_field = [0.0, 0.0, 1.0]
[integrator]
dt = 0.01
steps = 10
[mobility]
method = "direct"
[output]
trajectory_every = 5
"""


def test_simulation_with_rotation_reproduces_run_bd(tmp_path: Path):
    # Orientations (w, x, y, z) follow the trajectory's orientation column, written x y z w.
    rpyfmm.run_bd(ROTATING, out_dir=str(tmp_path))
    rows = (tmp_path / "trajectory.xyz").read_text().splitlines()
    assert "orientation:R:4" in rows[1]
    last = np.array([[float(v) for v in r.split()[5:9]] for r in rows[-27:]])
    sim = rpyfmm.Simulation.from_config(ROTATING)
    assert sim.orientations.shape == (27, 4)
    np.testing.assert_array_equal(sim.orientations[:, 0], 1.0)  # the identity at the start
    sim.run(10)
    np.testing.assert_allclose(sim.orientations[:, [1, 2, 3, 0]], last, rtol=0, atol=1e-9)  # 10 digits
    np.testing.assert_allclose(np.linalg.norm(sim.orientations, axis=1), 1.0, rtol=0, atol=1e-14)
    plain = rpyfmm.Simulation(np.zeros((1, 3)), dt=0.01, mobility="none")
    assert plain.orientations.shape == (0, 4)


def test_python_force_gives_exact_drift():
    x0 = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0, 10.0, 0.0]])
    g = np.array([0.3, -0.2, 0.1])
    calls = []

    def force(x: np.ndarray, step: int, f: np.ndarray) -> None:
        calls.append(step)
        assert x.shape == f.shape == (3, 3) and not x.flags.writeable
        f += g

    sim = rpyfmm.Simulation(x0, radius=1.5, dt=0.01, kT=0.0, mobility="none", viscosity=2.0, force=force)
    sim.run(10)
    assert calls == list(range(10))
    expected = x0 + g * 10 * 0.01 / (6 * np.pi * 2.0 * 1.5)
    np.testing.assert_allclose(sim.positions, expected, rtol=1e-14, atol=1e-15)
    # A returned array is added; the same result as the built-in external force.
    a = rpyfmm.Simulation(x0, radius=1.5, dt=0.01, kT=0.0, mobility="none", viscosity=2.0,
                          force=lambda x, s, f: np.tile(g, (3, 1)))
    b = rpyfmm.Simulation(x0, radius=1.5, dt=0.01, kT=0.0, mobility="none", viscosity=2.0, external_force=g)
    a.run(10)
    b.run(10)
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.positions, sim.positions)


def test_force_exception_propagates_and_keeps_state():
    x0 = np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]])

    def force(x, step, f):
        if step == 3:
            raise ZeroDivisionError("force failed at step 3")

    sim = rpyfmm.Simulation(x0, dt=0.01, seed=2, mobility="direct", force=force)
    sim.run(3)
    before = sim.positions.copy()
    with pytest.raises(ZeroDivisionError, match="force failed at step 3"):
        sim.step()
    assert sim.step_count == 3
    np.testing.assert_array_equal(sim.positions, before)

    bad = rpyfmm.Simulation(x0, dt=0.01, mobility="none", force=lambda x, s, f: np.zeros(5))
    with pytest.raises(rpyfmm.InvalidInputError, match="force callback: returned forces has shape"):
        bad.step()


def test_positions_view_is_live_read_only_and_not_copied():
    x0 = np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0], [0.0, 3.0, 0.0]])
    sim = rpyfmm.Simulation(x0, radius=[1.0, 0.5, 1.0], dt=0.01, mobility="direct", pair="wca")
    np.testing.assert_array_equal(sim.radii, [1.0, 0.5, 1.0])
    view = sim.positions
    address = view.ctypes.data
    sim.step()
    assert sim.positions.ctypes.data == address and not view.flags.writeable
    assert not np.array_equal(view, x0)  # updated in place
    assert sim.last_report.mobility_products >= 1
    refs = sys.getrefcount(sim)
    del view
    assert sys.getrefcount(sim) == refs - 1  # the view kept the simulation alive


def test_bd_with_hi_is_brownian():
    """Dilute HI suspension: the MSD over a short time is close to 6 D0 t (free diffusion)."""
    n = 27
    grid = np.stack(np.meshgrid(*[np.arange(3)] * 3, indexing="ij"), -1).reshape(-1, 3) * 15.0
    sim = rpyfmm.Simulation(grid, radius=1.0, dt=0.05, kT=1.0, seed=5, mobility="fmm", tolerance=1e-4)
    sim.run(40)
    d0 = rpyfmm.stokes_einstein(1.0, 1.0, 1.0)
    msd = rpyfmm.msd(np.stack([grid, sim.positions]))[-1]
    expected = 6 * d0 * sim.time
    assert abs(msd - expected) < 0.35 * expected  # 81 degrees of freedom: ~16% standard error


def test_sampler_preconditioner_reported_and_selectable(tmp_path: Path):
    """BD samples by block-preconditioned Lanczos by default (the report names its blocks);
    sqrt_preconditioner='none' gives M^{1/2} z; both drift identically without noise."""
    x = 2.5 * np.indices((4, 4, 4)).reshape(3, -1).T.astype(float)
    runs = {}
    for pre in ("auto", "none"):
        sim = rpyfmm.Simulation(x, radius=1.0, dt=0.01, kT=1.0, seed=3, mobility="direct", sqrt_preconditioner=pre)
        sim.run(2)
        runs[pre] = (sim.last_report.preconditioner_blocks, sim.positions.copy())
    assert runs["auto"][0] == 4 and runs["none"][0] == 0  # 64 particles, blocks of at most 16
    assert not np.allclose(runs["auto"][1], runs["none"][1])  # a different (equally valid) noise
    summary = rpyfmm.run_bd(CONFIG, steps=2, out_dir=str(tmp_path))
    assert summary["preconditioner_blocks"] == 2  # 30 particles in the config's direct run
    with pytest.raises(rpyfmm.Error, match="needs sqrt_method"):
        rpyfmm.Simulation(x, radius=1.0, dt=0.01, mobility="direct", sqrt_method="eigen",
                          sqrt_preconditioner="block")
    sim = rpyfmm.Simulation(x, radius=1.0, dt=0.01, kT=1.0, seed=3, mobility="direct", sqrt_method="chebyshev")
    sim.run(1)
    assert sim.last_report.preconditioner_blocks == 4  # 'auto' preconditions Chebyshev too
