"""One name for accuracy: `tolerance` (and `sqrt_tolerance`) in every keyword. The former
spellings (eps=, tol=, sqrt_tol=) still work with a DeprecationWarning and give the same result;
both spellings with different values raise InvalidArgumentError."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import rpyfmm
from conftest import suspension


def ready_direct(n: int = 20) -> rpyfmm.DirectRpy:
    op = rpyfmm.DirectRpy()
    op.set_positions(suspension(n), 1.0)
    return op


def test_laplace_fmm_tolerance():
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the current name warns about nothing
        assert rpyfmm.LaplaceFmm(tolerance=1e-9).tolerance == 1e-9
        assert rpyfmm.LaplaceFmm(1e-9).tolerance == 1e-9
        assert rpyfmm.LaplaceFmm().tolerance == 1e-6
        assert rpyfmm.fmm_default_leaf_capacity(tolerance=1e-9) == rpyfmm.fmm_default_leaf_capacity(1e-9)
    with pytest.warns(DeprecationWarning, match="eps= is deprecated; use tolerance="):
        old = rpyfmm.LaplaceFmm(eps=1e-9)
    assert old.tolerance == 1e-9
    with pytest.warns(DeprecationWarning, match="LaplaceFmm.tolerance"):
        assert old.eps == 1e-9
    with pytest.warns(DeprecationWarning):
        assert rpyfmm.fmm_default_leaf_capacity(eps=1e-9) == rpyfmm.fmm_default_leaf_capacity(1e-9)
    with pytest.warns(DeprecationWarning):
        assert rpyfmm.LaplaceFmm(tolerance=1e-9, eps=1e-9).tolerance == 1e-9
    with pytest.warns(DeprecationWarning), pytest.raises(rpyfmm.InvalidArgumentError, match="different values"):
        rpyfmm.LaplaceFmm(tolerance=1e-9, eps=1e-6)


def test_laplace_fmm_same_result_under_either_name():
    rng = np.random.default_rng(3)
    x, q = rng.uniform(-1, 1, (2000, 3)), rng.uniform(-1, 1, 2000)
    new = rpyfmm.LaplaceFmm(tolerance=1e-3)
    new.set_points(x)
    with pytest.warns(DeprecationWarning):
        old = rpyfmm.LaplaceFmm(eps=1e-3)
    old.set_points(x)
    np.testing.assert_array_equal(new.evaluate(q), old.evaluate(q))


@pytest.mark.parametrize("block", [False, True])
def test_apply_sqrt_tolerance(block: bool):
    op = ready_direct()
    z = rpyfmm.normal_noise(len(op), seed=4)
    if block:
        z = np.stack([z, 2.0 * z])
    apply = op.apply_sqrt_block if block else op.apply_sqrt
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        w, _ = apply(z, method="lanczos", tolerance=1e-6)
    with pytest.warns(DeprecationWarning, match="tol= is deprecated; use tolerance="):
        w_old, _ = apply(z, method="lanczos", tol=1e-6)
    np.testing.assert_array_equal(w, w_old)
    with pytest.warns(DeprecationWarning), pytest.raises(rpyfmm.InvalidArgumentError, match="different values"):
        apply(z, tolerance=1e-6, tol=1e-4)


def test_sqrt_apply_tolerance():
    m = np.diag(np.linspace(1.0, 2.0, 12))
    z = np.ones(12)
    w, _ = rpyfmm.sqrt_apply(lambda v: m @ v, z, tolerance=1e-10)
    with pytest.warns(DeprecationWarning, match="tol= is deprecated"):
        w_old, _ = rpyfmm.sqrt_apply(lambda v: m @ v, z, tol=1e-10)
    np.testing.assert_array_equal(w, w_old)
    with pytest.warns(DeprecationWarning), pytest.raises(rpyfmm.InvalidArgumentError, match="different values"):
        rpyfmm.sqrt_apply(lambda v: m @ v, z, tolerance=1e-10, tol=1e-3)


def test_deprecation_as_error_raises_it():
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        with pytest.raises(DeprecationWarning):
            rpyfmm.LaplaceFmm(eps=1e-6)


def test_simulation_sqrt_tolerance():
    x = suspension(30)
    kwargs = dict(dt=0.01, seed=3, mobility="direct", sqrt_method="lanczos")
    new = rpyfmm.Simulation(x, 1.0, sqrt_tolerance=1e-5, **kwargs)
    with pytest.warns(DeprecationWarning, match="sqrt_tol= is deprecated; use sqrt_tolerance="):
        old = rpyfmm.Simulation(x, 1.0, sqrt_tol=1e-5, **kwargs)
    new.run(2)
    old.run(2)
    np.testing.assert_array_equal(new.positions, old.positions)
    with pytest.warns(DeprecationWarning), pytest.raises(rpyfmm.InvalidArgumentError, match="different values"):
        rpyfmm.Simulation(x, 1.0, sqrt_tolerance=1e-5, sqrt_tol=1e-3, **kwargs)


def test_rigid_sqrt_tolerance():
    beads = rpyfmm.icosphere_beads(1) * 2.0
    x = np.concatenate([beads, beads + [6.0, 0.0, 0.0]])
    a = 0.5 * rpyfmm.icosphere_bead_radius(1) * 2.0
    offsets = [0, len(beads), 2 * len(beads)]
    bodies = rpyfmm.RigidBodies(rpyfmm.DirectRpy(), tolerance=1e-10)
    bodies.set_configuration(x, a, offsets)
    w, z = np.ones((2, 6)), rpyfmm.normal_noise(len(x), seed=2)
    u, _ = bodies.apply_with_noise(w, 0.5, z, sqrt_tolerance=1e-6)
    with pytest.warns(DeprecationWarning, match="sqrt_tol= is deprecated"):
        u_old, _ = bodies.apply_with_noise(w, 0.5, z, sqrt_tol=1e-6)
    np.testing.assert_array_equal(u, u_old)

    shape = beads - beads.mean(axis=0)
    q0 = np.array([[0.0, 0.0, 0.0]])
    kwargs = dict(dt=0.01, seed=4, tolerance=1e-8)
    new = rpyfmm.RigidBodyDynamics(rpyfmm.DirectRpy(), shape, a, [0, len(beads)], q0, sqrt_tolerance=1e-5, **kwargs)
    with pytest.warns(DeprecationWarning, match="sqrt_tol= is deprecated"):
        old = rpyfmm.RigidBodyDynamics(rpyfmm.DirectRpy(), shape, a, [0, len(beads)], q0, sqrt_tol=1e-5, **kwargs)
    new.run(2)
    old.run(2)
    np.testing.assert_array_equal(new.positions, old.positions)


def test_fmm_rpy_laplace_tolerance():
    op = rpyfmm.FmmRpy(tolerance=1e-6)
    op.set_positions(suspension(200), 1.0)
    with pytest.warns(DeprecationWarning, match="laplace_tolerance"):
        assert op.laplace_eps == op.laplace_tolerance
