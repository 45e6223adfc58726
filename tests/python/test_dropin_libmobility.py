"""rpyfmm.libmobility, the libMobility drop-in: the same numbers as rpyfmm's own operators for the
same script, a NumPy RPY matrix as an independent reference, libMobility's conventions for
sqrtMdotW, LangevinVelocities and the earlier hydrodynamicVelocities, shapes, and clear errors for
what is not supported or malformed."""

from __future__ import annotations

import math
import sys
import types

import numpy as np
import pytest

import rpyfmm
from conftest import suspension
from rpyfmm.libmobility import PSE, DPStokes, NBody, SelfMobility

ETA, A = 1.3, 0.9


def rpy_dense(x: np.ndarray, a: float, eta: float) -> np.ndarray:
    """(3N, 3N) RPY mobility of equal spheres (Rotne-Prager-Yamakawa, with the overlap form)."""
    n = len(x)
    m = np.zeros((3 * n, 3 * n))
    mu0 = 1.0 / (6.0 * math.pi * eta * a)
    for i in range(n):
        m[3 * i:3 * i + 3, 3 * i:3 * i + 3] = mu0 * np.eye(3)
        for j in range(i + 1, n):
            d = x[i] - x[j]
            r = np.linalg.norm(d)
            rr = np.outer(d, d) / r**2
            if r > 2.0 * a:
                block = (1.0 / (8.0 * math.pi * eta * r)) * (
                    (1.0 + 2.0 * a**2 / (3.0 * r**2)) * np.eye(3) + (1.0 - 2.0 * a**2 / r**2) * rr)
            else:
                block = mu0 * ((1.0 - 9.0 * r / (32.0 * a)) * np.eye(3) + (3.0 * r / (32.0 * a)) * rr)
            m[3 * i:3 * i + 3, 3 * j:3 * j + 3] = block
            m[3 * j:3 * j + 3, 3 * i:3 * i + 3] = block
    return m


@pytest.fixture(scope="module")
def system() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(21)
    x = suspension(60, radius=A, spacing=2.2, seed=4)  # a few overlapping pairs
    return x, rng.standard_normal(x.shape), rng.standard_normal(x.shape)


def nbody(algorithm: str = "advise", angular: bool = False, seed: int = 9, **init) -> NBody:
    solver = NBody("open", "open", "open")
    solver.setParameters(algorithm=algorithm)
    solver.initialize(viscosity=ETA, hydrodynamicRadius=A, includeAngular=angular, seed=seed, **init)
    return solver


def test_nbody_mdot_is_direct_rpy_and_the_numpy_matrix(system):
    x, f, t = system
    solver = nbody()
    solver.setPositions(x)
    u, w = solver.Mdot(f)
    assert w is None and u.shape == x.shape and u.dtype == np.float64
    op = rpyfmm.DirectRpy(viscosity=ETA)
    op.set_positions(x, A)
    np.testing.assert_array_equal(u, op.apply(f))
    np.testing.assert_allclose(u.ravel(), rpy_dense(x, A, ETA) @ f.ravel(), rtol=1e-12, atol=1e-14)


def test_nbody_with_torques_is_the_grand_mobility(system):
    x, f, t = system
    solver = nbody(angular=True)
    solver.setPositions(x)
    op = rpyfmm.DirectRpy(viscosity=ETA)
    op.set_positions(x, A)
    for args, ref in (((f, t), op.apply(f, t)), ((None, t), op.apply(np.zeros_like(f), t)),
                      ((f, None), op.apply(f, np.zeros_like(t)))):
        u, w = solver.Mdot(*args)
        np.testing.assert_array_equal(u, ref[0])
        np.testing.assert_array_equal(w, ref[1])
    # translation block of the grand mobility = the RPY matrix
    np.testing.assert_allclose(solver.Mdot(f)[0].ravel(), rpy_dense(x, A, ETA) @ f.ravel(), rtol=1e-12, atol=1e-14)


def test_nbody_fmm_algorithm_is_fmm_rpy(system):
    x, f, t = system
    solver = nbody(algorithm="fmm", angular=True, tolerance=1e-6)
    solver.setPositions(x)
    op = rpyfmm.FmmRpy(viscosity=ETA, tolerance=1e-6)
    op.set_positions(x, A)
    u, w = solver.Mdot(f, t)
    ref = op.apply(f, t)
    np.testing.assert_array_equal(u, ref[0])
    np.testing.assert_array_equal(w, ref[1])


def test_nbody_advise_picks_direct_or_fmm_by_n():
    crossover = rpyfmm.default_fmm_crossover(1e-4)
    solver = nbody()
    for n, name in ((10, "direct"), (crossover + 10, "fmm"), (12, "direct")):
        solver.setPositions(suspension(n, radius=A, spacing=2.5, seed=n))
        assert solver._op.name == name and solver.getNumberParticles() == n


def test_pse_mdot_is_pse_rpy(system):
    x, f, _ = system
    box = (16.0, 17.0, 18.0)
    solver = PSE("periodic", "periodic", "periodic")
    solver.setParameters(psi=0.5, Lx=box[0], Ly=box[1], Lz=box[2])
    solver.initialize(viscosity=ETA, hydrodynamicRadius=A, tolerance=1e-5)
    solver.setPositions(x)
    u, w = solver.Mdot(forces=f.ravel())
    assert w is None and u.shape == (3 * len(x),)
    op = rpyfmm.PseRpy(box=box, viscosity=ETA, tolerance=1e-5, xi=0.5)
    op.set_positions(x, A)
    np.testing.assert_array_equal(u, op.apply(f).ravel())


def test_pse_with_torques_is_pse_rpy_grand_mobility(system):
    x, f, t = system
    box = (16.0, 17.0, 18.0)
    solver = PSE("periodic", "periodic", "periodic")
    solver.setParameters(psi=0.0, Lx=box[0], Ly=box[1], Lz=box[2])
    solver.initialize(viscosity=ETA, hydrodynamicRadius=A, includeAngular=True, tolerance=1e-5, seed=2)
    solver.setPositions(x)
    u, w = solver.Mdot(f, t)
    op = rpyfmm.PseRpy(box=box, viscosity=ETA, tolerance=1e-5)
    op.set_positions(x, A)
    ref = op.apply(f, t)
    np.testing.assert_array_equal(u, ref[0])
    np.testing.assert_array_equal(w, ref[1])
    du, dw = solver.sqrtMdotW()
    n = len(x)
    wt, wr, _ = op.apply_sqrt_rotation(rpyfmm.normal_noise(n, 2, 0), rpyfmm.normal_noise(n, 2, 0, stream=3),
                                       tolerance=1e-5)
    np.testing.assert_array_equal(du, wt)
    np.testing.assert_array_equal(dw, wr)


def test_self_mobility_is_free_draining(system):
    x, f, t = system
    solver = SelfMobility("open", "open", "open")
    solver.setParameters(parameter=5.0)
    solver.initialize(viscosity=ETA, hydrodynamicRadius=A, includeAngular=True)
    solver.setPositions(x)
    u, w = solver.Mdot(f, t)
    np.testing.assert_allclose(u, f / (6.0 * math.pi * ETA * A), rtol=1e-14)
    np.testing.assert_allclose(w, t / (8.0 * math.pi * ETA * A**3), rtol=1e-14)


def test_sqrtmdotw_is_prefactor_times_the_operators_root(system):
    x, _, _ = system
    solver = nbody(seed=77)
    solver.setPositions(x.ravel())
    op = rpyfmm.DirectRpy(viscosity=ETA)
    op.set_positions(x, A)
    for step in range(2):  # each call draws new noise: step = call count
        u, w = solver.sqrtMdotW(prefactor=0.5)
        ref, _ = op.apply_sqrt(rpyfmm.normal_noise(len(x), 77, step), tolerance=1e-4)
        assert w is None and u.shape == (3 * len(x),)  # the positions' shape
        np.testing.assert_array_equal(u, 0.5 * ref.ravel())
    again = nbody(seed=77)
    again.setPositions(x)
    np.testing.assert_array_equal(again.sqrtMdotW(0.5)[0].ravel(), nbody_first(x, 77))


def nbody_first(x: np.ndarray, seed: int) -> np.ndarray:
    solver = nbody(seed=seed)
    solver.setPositions(x)
    return solver.sqrtMdotW(0.5)[0].ravel()


def test_sqrtmdotw_covariance_is_the_mobility():
    """Independent of the sampler: over many draws, E[w w^T] = M (prefactor 1)."""
    x = np.array([[0.0, 0.0, 0.0], [2.1, 0.3, 0.0], [0.5, 1.9, 0.4]])
    solver = nbody(seed=3)
    solver.setPositions(x)
    samples = np.array([solver.sqrtMdotW()[0].ravel() for _ in range(4000)])
    cov = samples.T @ samples / len(samples)
    m = rpy_dense(x, A, ETA)
    assert np.linalg.norm(cov - m) < 0.08 * np.linalg.norm(m)


def test_angular_noise_covariance_of_self_mobility():
    solver = SelfMobility("open", "open", "open")
    solver.initialize(viscosity=ETA, hydrodynamicRadius=A, includeAngular=True, seed=5)
    solver.setPositions(np.random.default_rng(0).uniform(0, 50, size=(3000, 3)))
    u, w = solver.sqrtMdotW(prefactor=2.0)
    np.testing.assert_allclose(np.mean(u * u), 4.0 / (6.0 * math.pi * ETA * A), rtol=0.05)
    np.testing.assert_allclose(np.mean(w * w), 4.0 / (8.0 * math.pi * ETA * A**3), rtol=0.05)
    assert abs(np.mean(u * w)) < 0.05 * math.sqrt(np.mean(u * u) * np.mean(w * w))  # independent noises


def test_angular_sqrtmdotw_is_the_operators_rotation_sampler(system):
    x, _, _ = system
    solver = nbody(angular=True, seed=31)
    solver.setPositions(x)
    u, w = solver.sqrtMdotW(prefactor=1.5)
    op = rpyfmm.DirectRpy(viscosity=ETA)
    op.set_positions(x, A)
    n = len(x)
    wt, wr, _ = op.apply_sqrt_rotation(rpyfmm.normal_noise(n, 31, 0), rpyfmm.normal_noise(n, 31, 0, stream=3),
                                       tolerance=1e-4)
    np.testing.assert_array_equal(u, 1.5 * wt)
    np.testing.assert_array_equal(w, 1.5 * wr)


def test_langevin_velocities_is_mdot_plus_scaled_noise(system):
    x, f, t = system
    dt, kbt = 0.01, 0.7
    a = nbody(angular=True, seed=12)
    b = nbody(angular=True, seed=12)
    for s in (a, b):
        s.setPositions(x)
    u, w = a.LangevinVelocities(dt, kbt, forces=f, torques=t)
    mu, mw = b.Mdot(f, t)
    nu, nw = b.sqrtMdotW(math.sqrt(2.0 * kbt / dt))
    np.testing.assert_allclose(u, mu + nu, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(w, mw + nw, rtol=1e-13, atol=1e-15)
    np.testing.assert_array_equal(a.LangevinVelocities(dt, 0.0, forces=f)[0], b.Mdot(f)[0])
    noise_only = a.LangevinVelocities(dt, kbt)
    assert noise_only[0].shape == x.shape and np.any(noise_only[0] != 0.0)
    lin, ang = a.divM()
    assert not lin.any() and not ang.any()


def test_earlier_spelling_with_temperature(system):
    """libMobility before 0.9: sqrtMdotW and hydrodynamicVelocities include sqrt(2 kT)."""
    x, f, _ = system
    kT = 2.0
    old = NBody("open", "open", "open")
    old.initialize(temperature=kT, viscosity=ETA, hydrodynamicRadius=A, needsTorque=False, seed=4,
                   numberParticles=len(x))
    old.setPositions(x)
    new = nbody(seed=4)
    new.setPositions(x)
    np.testing.assert_allclose(old.sqrtMdotW(3.0)[0], 3.0 * math.sqrt(2.0 * kT) * new.sqrtMdotW(1.0)[0],
                               rtol=1e-13, atol=1e-15)
    u, _ = old.hydrodynamicVelocities(f, None, 0.5)
    np.testing.assert_allclose(u, new.Mdot(f)[0] + 0.5 * math.sqrt(2.0 * kT) * new.sqrtMdotW(1.0)[0],
                               rtol=1e-13, atol=1e-15)
    assert not old.thermalDrift(1.0)[0].any()
    with pytest.raises(rpyfmm.NotSupportedError, match="LangevinVelocities"):
        new.hydrodynamicVelocities(f)
    with pytest.raises(rpyfmm.InvalidInputError, match="numberParticles"):
        old.setPositions(x[:5])


def test_shapes_follow_libmobility(system):
    x, f, t = system
    solver = nbody(angular=True)
    solver.setPositions(x)
    u, w = solver.Mdot(forces=f.ravel(), torques=t)
    assert u.shape == (3 * len(x),) and w.shape == x.shape
    u, w = solver.Mdot(torques=t.ravel())
    assert u.shape == w.shape == (3 * len(x),)
    assert solver.getNumberParticles() == len(x) and NBody.precision == "double"


@pytest.mark.parametrize(
    "make,error,match",
    [
        (lambda: NBody("open", "open", "single_wall"), rpyfmm.NotSupportedError, "single_wall.*no wall mobility"),
        (lambda: NBody("periodic", "periodic", "periodic"), rpyfmm.NotSupportedError, "NBody takes"),
        (lambda: PSE("periodic", "periodic", "open"), rpyfmm.NotSupportedError, "PSE takes"),
        (lambda: SelfMobility("open", "open", "two_walls"), rpyfmm.NotSupportedError, "two_walls"),
        (lambda: NBody("open", "closed", "open"), rpyfmm.InvalidArgumentError, "periodicityY = 'closed'"),
        (lambda: DPStokes("periodic", "periodic", "single_wall"), rpyfmm.NotSupportedError, "DPStokes"),
    ],
)
def test_unsupported_geometries_are_refused_by_name(make, error, match):
    with pytest.raises(error, match=match):
        make()


def test_unsupported_options_are_refused_by_name():
    solver = NBody("open", "open", "open")
    with pytest.raises(rpyfmm.NotSupportedError, match="wallHeight"):
        solver.setParameters(wallHeight=1.0)
    with pytest.raises(rpyfmm.NotSupportedError, match="Nbatch"):
        solver.setParameters(Nbatch=4, NperBatch=10)
    with pytest.raises(rpyfmm.InvalidArgumentError, match="algorithm"):
        solver.setParameters(algorithm="tree")
    with pytest.raises(rpyfmm.NotSupportedError, match="lanczos_callback"):
        solver.initialize(viscosity=1.0, hydrodynamicRadius=1.0, lanczos_callback=print)
    pse = PSE("periodic", "periodic", "periodic")
    with pytest.raises(rpyfmm.InvalidArgumentError, match="setParameters"):
        pse.initialize(viscosity=1.0, hydrodynamicRadius=1.0)
    with pytest.raises(rpyfmm.NotSupportedError, match="shearStrain"):
        pse.setParameters(psi=0.5, Lx=10, Ly=10, Lz=10, shearStrain=0.1)
    with pytest.raises(TypeError, match="bogus"):
        solver.initialize(viscosity=1.0, hydrodynamicRadius=1.0, bogus=3)


def test_bad_input_raises_clear_errors(system):
    x, f, t = system
    solver = NBody("open", "open", "open")
    with pytest.raises(rpyfmm.InvalidArgumentError, match="call initialize first"):
        solver.setPositions(x)
    with pytest.raises(ValueError, match="includeAngular must be True or False .*temperature="):
        solver.initialize(1.0, 1.0, 1.0)  # the pre-0.9 positional order (temperature first)
    with pytest.raises(ValueError, match="viscosity must be > 0"):
        solver.initialize(viscosity=0.0, hydrodynamicRadius=1.0)
    solver.initialize(viscosity=1.0, hydrodynamicRadius=1.0)
    with pytest.raises(rpyfmm.InvalidArgumentError, match="call setPositions first"):
        solver.Mdot(f)
    with pytest.raises(rpyfmm.InvalidInputError, match=r"positions has shape \(60, 2\)"):
        solver.setPositions(x[:, :2])
    bad = x.copy()
    bad[3, 1] = np.nan
    with pytest.raises(rpyfmm.InvalidInputError, match=r"positions entry \(3, 1\) is nan"):
        solver.setPositions(bad)
    solver.setPositions(x)
    with pytest.raises(rpyfmm.InvalidInputError, match="forces has 30 entries, expected 3N = 180"):
        solver.Mdot(f[:10])
    with pytest.raises(rpyfmm.InvalidArgumentError, match="includeAngular=False"):
        solver.Mdot(f, t)
    with pytest.raises(rpyfmm.InvalidArgumentError, match="give forces, torques or both"):
        solver.Mdot()
    with pytest.raises(rpyfmm.InvalidArgumentError, match="dt must be > 0"):
        solver.LangevinVelocities(0.0, 1.0, forces=f)
    solver.clean()
    with pytest.raises(rpyfmm.InvalidArgumentError, match="call initialize first"):
        solver.Mdot(f)


# ---- host arrays of other frameworks -------------------------------------------------------------


class HostFrameArray:
    """A host array of a stand-in framework "hostframe" (DLPack on kDLCPU, read by NumPy through
    __array__), as a PyTorch CPU tensor presents itself."""

    def __init__(self, a: np.ndarray) -> None:
        self.a = a

    def __array__(self, dtype=None, copy=None):
        return self.a if dtype is None else self.a.astype(dtype)

    def __dlpack__(self, **kwargs):
        return self.a.__dlpack__(**kwargs)

    def __dlpack_device__(self):
        return self.a.__dlpack_device__()


@pytest.fixture
def hostframe(monkeypatch):
    module = types.ModuleType("hostframe")
    module.from_dlpack = lambda x: HostFrameArray(np.from_dlpack(x))
    HostFrameArray.__module__ = "hostframe"
    monkeypatch.setitem(sys.modules, "hostframe", module)
    return HostFrameArray


def test_host_arrays_of_another_framework_come_back_in_it(system, hostframe):
    # libMobility returns its results in the input's framework: the values are the NumPy call's
    # bits (the same operator and vectors), wrapped without a copy.
    x, f, t = system
    ref, solver = nbody(angular=True), nbody(angular=True)
    ref.setPositions(x)
    solver.setPositions(hostframe(x))
    for got, want in ((solver.Mdot(hostframe(f)), ref.Mdot(f)),
                      (solver.Mdot(torques=hostframe(t)), ref.Mdot(torques=t)),
                      (solver.sqrtMdotW(0.5), ref.sqrtMdotW(0.5)),  # the positions' framework
                      (solver.divM(), ref.divM())):
        for g, w in zip(got, want):
            assert isinstance(g, hostframe)
            np.testing.assert_array_equal(g.a, w)
    # NumPy forces on hostframe positions give NumPy, as the input's framework decides.
    u, _ = solver.Mdot(f)
    assert isinstance(u, np.ndarray)
    # NumPy positions give NumPy for the calls without an array argument.
    solver.setPositions(x)
    assert isinstance(solver.sqrtMdotW()[0], np.ndarray)


def test_torch_cpu_tensors_in_torch_tensors_out(system):
    torch = pytest.importorskip("torch")
    x, f, _ = system
    ref, solver = nbody(), nbody()
    ref.setPositions(x)
    solver.setPositions(torch.from_numpy(x))
    u, w = solver.Mdot(torch.from_numpy(f))
    assert isinstance(u, torch.Tensor) and u.dtype == torch.float64 and w is None
    np.testing.assert_array_equal(u.numpy(), ref.Mdot(f)[0])
    noise = solver.sqrtMdotW()[0]
    assert isinstance(noise, torch.Tensor)
    np.testing.assert_array_equal(noise.numpy(), ref.sqrtMdotW()[0])
