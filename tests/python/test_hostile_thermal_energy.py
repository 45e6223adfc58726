"""A thermal energy that is subnormal, or whose noise variance under- or overflows, is refused
the same way by every entry point: Simulation and RunConfig (through the C++ Integrator), a TOML
config, RigidBodyDynamics, and stokes_einstein. Before, Simulation(kT=5e-324) ran with kT > 0 and
Brownian displacements of exactly 0 (2 kT dt underflowed), and stokes_einstein returned inf for a
subnormal viscosity.
"""
from __future__ import annotations

import numpy as np
import pytest

import rpyfmm

X = np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]])


@pytest.mark.parametrize("kT,dt,fragment", [
    (5e-324, 0.01, "kT must be 0 or a normal number"),
    (1e-310, 0.01, "kT must be 0 or a normal number"),
    (1e-200, 1e-200, "2 kT dt = 0"),
    (1e200, 1e200, "2 kT dt = inf"),
])
def test_simulation_refuses_noise_lost_to_rounding(kT, dt, fragment):
    with pytest.raises(rpyfmm.InvalidArgumentError, match=fragment):
        rpyfmm.Simulation(X, 1.0, dt=dt, kT=kT, mobility="none")


def test_zero_kT_is_deterministic_dynamics():
    sim = rpyfmm.Simulation(X, 1.0, dt=0.01, kT=0.0, mobility="none")
    sim.run(3)
    np.testing.assert_array_equal(sim.positions, X)


def test_toml_config_names_the_key(tmp_path):
    path = tmp_path / "run.toml"
    path.write_text('[system]\nkT = 5e-324\n[particles]\nsource = "random"\ncount = 10\n'
                    '[integrator]\ndt = 0.01\nsteps = 1\n')
    with pytest.raises(rpyfmm.InvalidArgumentError, match="'system.kT' must be 0 or a normal number"):
        rpyfmm.load_config(str(path))


def test_rigid_body_dynamics_refuses_subnormal_kT():
    shape = rpyfmm.icosphere_beads(1)
    a = rpyfmm.icosphere_bead_radius(1)
    with pytest.raises(rpyfmm.InvalidArgumentError, match="kT must be 0 or a normal number"):
        rpyfmm.RigidBodyDynamics(rpyfmm.DirectRpy(), shape, a, [0, 42], np.zeros((1, 3)), dt=0.01, kT=5e-324)


@pytest.mark.parametrize("args,fragment", [
    ((5e-324, 1.0, 1.0), "kT must be a normal number"),
    ((1.0, 5e-324, 1e-10), "viscosity must be a normal number"),
    ((1.0, 1.0, 1e-310), "radius must be a normal number"),
    ((1e300, 1e-300, 1e-10), r"kT / \(6 pi eta a\) overflows"),
])
def test_stokes_einstein_refuses_subnormal_scales(args, fragment):
    with pytest.raises(rpyfmm.InvalidArgumentError, match="stokes_einstein: " + fragment):
        rpyfmm.stokes_einstein(*args)
