"""Rigid bodies of beads from Python: the body mobility against a dense NumPy solve of the
saddle-point system (N = (K^T M^{-1} K)^{-1}, M from DirectRpy.assemble_dense), from zero and from a
guess (apply_from), bead forces, reference points, the bead-shell shapes, and errors."""

from __future__ import annotations

import numpy as np
import pytest

import rpyfmm
from conftest import rel_err


def two_shells_and_a_triangle():
    shell = rpyfmm.icosphere_beads(1)
    a = 2.0 * rpyfmm.icosphere_bead_radius(1)
    tri = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.0, 1.7, 0.0], [1.0, 0.6, 1.6]])
    x = np.vstack([2.0 * shell, 2.0 * shell + [7.0, 1.0, -1.0], tri + [0.0, 8.0, 3.0]])
    radii = np.concatenate([np.full(84, a), np.full(4, 1.0)])
    return x, radii, [0, 42, 84, 88]


def dense_body_mobility(op, x, offsets):
    m = np.array(op.assemble_dense())
    k = np.zeros((3 * len(x), 6 * (len(offsets) - 1)))
    for b in range(len(offsets) - 1):
        beads = slice(offsets[b], offsets[b + 1])
        arms = x[beads] - x[beads].mean(axis=0)
        for j, r in zip(range(offsets[b], offsets[b + 1]), arms):
            k[3 * j:3 * j + 3, 6 * b:6 * b + 3] = np.eye(3)
            k[3 * j:3 * j + 3, 6 * b + 3:6 * b + 6] = -np.array(
                [[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]])  # Omega x r = -[r]_x Omega
    minv_k = np.linalg.solve(m, k)
    n = np.linalg.inv(k.T @ minv_k)
    return n, minv_k @ n


def test_body_mobility_matches_dense_solve():
    x, radii, offsets = two_shells_and_a_triangle()
    op = rpyfmm.DirectRpy(viscosity=1.3)
    bodies = rpyfmm.RigidBodies(op, tolerance=1e-11)
    bodies.set_configuration(x, radii, offsets)
    assert bodies.bodies == 3 and bodies.beads == 88
    n, bead_map = dense_body_mobility(op, x, offsets)
    w = np.random.default_rng(1).standard_normal((3, 6))
    u, report = bodies.apply(w)
    assert u.shape == (3, 6)
    assert rel_err(u.ravel(), n @ w.ravel()) < 1e-8
    assert report.iterations > 0 and report.residual <= 1e-11
    u2, lam, _ = bodies.apply_with_bead_forces(w.ravel())
    assert lam.shape == (88, 3)
    assert rel_err(lam.ravel(), bead_map @ w.ravel()) < 1e-7
    np.testing.assert_allclose(u2, u, rtol=0, atol=1e-14 * np.abs(u).max())
    np.testing.assert_allclose(bodies.reference_points[2], x[84:88].mean(axis=0), atol=1e-14)
    assert "RigidBodyReport(" in repr(report)


def test_apply_from_a_guess_matches_dense_solve():
    """apply_from: GMRES from the solution of forces and torques 1e-4 off meets the same tolerance in
    fewer iterations (measured 7 against 9 from zero; 1e-2 off saves none at this tolerance on three
    bodies); from the exact solution it stops after its first check."""
    x, radii, offsets = two_shells_and_a_triangle()
    op = rpyfmm.DirectRpy(viscosity=1.3)
    bodies = rpyfmm.RigidBodies(op, tolerance=1e-11)
    bodies.set_configuration(x, radii, offsets)
    n, bead_map = dense_body_mobility(op, x, offsets)
    w = np.random.default_rng(5).standard_normal((3, 6))
    nearby = w + 1e-4 * np.random.default_rng(6).standard_normal(w.shape)
    u_guess, lam_guess, from_zero = bodies.apply_with_bead_forces(nearby)
    u, lam, report = bodies.apply_from(w, u_guess, lam_guess)
    assert u.shape == (3, 6) and lam.shape == (88, 3)
    # The bounds of test_body_mobility_matches_dense_solve (GMRES at 1e-11 against the dense
    # solve's round-off on this conditioning).
    assert rel_err(u.ravel(), n @ w.ravel()) < 1e-8
    assert rel_err(lam.ravel(), bead_map @ w.ravel()) < 1e-7
    assert 0 < report.iterations < from_zero.iterations and report.residual <= 1e-11
    _, _, exact = bodies.apply_from(w, u, lam)
    assert exact.iterations <= 1
    with pytest.raises(rpyfmm.Error, match="guess velocities"):
        bodies.apply_from(w, np.full((3, 6), np.nan), lam)
    with pytest.raises(rpyfmm.Error, match="guess bead forces"):
        bodies.apply_from(w, u, lam[:-1])
    with pytest.raises(rpyfmm.InvalidInputError, match="guess_velocities"):
        bodies.apply_from(w, u[:, :5], lam)


def test_brownian_velocities():
    """apply_with_noise = N W + c N K^T M^{-1} M^{1/2} z (principal root: preconditioner 'none')."""
    x, radii, offsets = two_shells_and_a_triangle()
    op = rpyfmm.DirectRpy()
    bodies = rpyfmm.RigidBodies(op, tolerance=1e-11)
    bodies.set_configuration(x, radii, offsets)
    n, bead_map = dense_body_mobility(op, x, offsets)
    lam, v = np.linalg.eigh(np.array(op.assemble_dense()))
    root = (v * np.sqrt(lam)) @ v.T
    w = np.random.default_rng(3).standard_normal((3, 6))
    z = rpyfmm.normal_noise(len(x), seed=4)
    u, report = bodies.apply_with_noise(w, 0.7, z, sqrt_tolerance=1e-10, preconditioner="none")
    assert rel_err(u.ravel(), n @ w.ravel() + 0.7 * bead_map.T @ root @ z.ravel()) < 1e-7
    assert report.sqrt.iterations > 0 and report.sqrt.preconditioner_blocks == 0
    _, report = bodies.apply_with_noise(w, 0.7, z)  # default: block-preconditioned bead noise
    assert report.sqrt.preconditioner_blocks > 0
    with pytest.raises(rpyfmm.Error, match="noise_scale"):
        bodies.apply_with_noise(w, -1.0, z)


def test_mobility_matrix_of_a_bead_shell_sphere():
    """kT N of one bead shell: isotropic translational and rotational diffusion, no coupling, close
    to Stokes-Einstein for the shell's radius R = 1 (642 beads: 2.3% and 6.5% below 1/(6 pi eta R)
    and 1/(8 pi eta R^3); the shell's hydrodynamic radius exceeds R by a third of a bead radius)."""
    shell = rpyfmm.icosphere_beads(3)
    bodies = rpyfmm.RigidBodies(rpyfmm.DirectRpy(), tolerance=1e-10)
    bodies.set_configuration(shell, rpyfmm.icosphere_bead_radius(3), [0, len(shell)])
    n = bodies.mobility_matrix()
    assert n.shape == (6, 6)
    np.testing.assert_array_equal(n, n.T)
    np.testing.assert_allclose(n[:3, :3], n[0, 0] * np.eye(3), atol=1e-8 * n[0, 0])
    np.testing.assert_allclose(n[3:, 3:], n[3, 3] * np.eye(3), atol=1e-8 * n[3, 3])
    assert np.abs(n[:3, 3:]).max() < 1e-8 * np.sqrt(n[0, 0] * n[3, 3])
    assert 0.95 < n[0, 0] * 6 * np.pi < 1.0 and 0.9 < n[3, 3] * 8 * np.pi < 1.0


def test_reference_points_shift_the_angular_frame():
    """About another reference point q' = q + d, a body's velocity there is U + Omega x d and its
    torque T - d x F: the rigid motion is the same."""
    x, radii, offsets = two_shells_and_a_triangle()
    op = rpyfmm.DirectRpy()
    bodies = rpyfmm.RigidBodies(op, tolerance=1e-11)
    bodies.set_configuration(x, radii, offsets)
    w = np.random.default_rng(2).standard_normal((3, 6))
    u, _ = bodies.apply(w)
    q = bodies.reference_points
    d = np.array([[0.5, -1.0, 2.0], [0.0, 0.0, 0.0], [-3.0, 1.0, 0.5]])
    bodies.set_configuration(x, radii, offsets, reference_points=q + d)
    w2 = w.copy()
    w2[:, 3:] = w[:, 3:] - np.cross(d, w[:, :3])
    u2, _ = bodies.apply(w2)
    np.testing.assert_allclose(u2[:, 3:], u[:, 3:], rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(u2[:, :3], u[:, :3] + np.cross(u[:, 3:], d), rtol=1e-8, atol=1e-10)


def test_icosphere_beads():
    for s in range(4):
        v = rpyfmm.icosphere_beads(s)
        assert v.shape == (10 * 4**s + 2, 3)
        np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1.0, atol=1e-14)
    d = np.linalg.norm(v[:, None, :] - v[None, :, :], axis=2) + 10 * np.eye(len(v))
    assert abs(d.min() / 2 - rpyfmm.icosphere_bead_radius(3)) < 1e-12


def test_errors():
    x, radii, offsets = two_shells_and_a_triangle()
    op = rpyfmm.DirectRpy()
    with pytest.raises(rpyfmm.Error, match="tolerance"):
        rpyfmm.RigidBodies(op, tolerance=2.0)
    bodies = rpyfmm.RigidBodies(op)
    with pytest.raises(rpyfmm.Error, match="before set_configuration"):
        bodies.apply(np.zeros((3, 6)))
    with pytest.raises(rpyfmm.Error, match="end at"):
        bodies.set_configuration(x, radii, [0, 42, 84])
    with pytest.raises(rpyfmm.Error, match="one line"):
        bodies.set_configuration(np.array([[0.0, 0, 0], [2, 0, 0], [4, 0, 0]]), 1.0, [0, 3])
    bodies.set_configuration(x, np.float64(0.5), np.array(offsets))  # NumPy scalar radius, integer offsets
    bodies.set_configuration(x, radii, np.array(offsets))
    with pytest.raises(rpyfmm.Error, match="forces and torques"):
        bodies.apply(np.zeros((2, 6)))
    with pytest.raises(rpyfmm.Error, match="expected"):
        bodies.apply(np.zeros((3, 5)))
    with pytest.raises(rpyfmm.Error, match="NaN"):
        bodies.apply(np.full((3, 6), np.nan))
    with pytest.raises(rpyfmm.Error, match="subdivisions"):
        rpyfmm.icosphere_beads(9)
