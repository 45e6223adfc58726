"""Brownian samplers on the grand mobility with rotation from Python (op.apply_sqrt_rotation):
against the dense 6N x 6N matrix from op.apply(F, T) with unit vectors and NumPy's
eigendecomposition of the scaled S M S (docs/theory/samplers.md, "Rotation"), the CLI's
`sample --angular` bit for bit, free draining exactly, and refusals."""

from __future__ import annotations

import numpy as np
import pytest

import rpyfmm
from conftest import rel_err, suspension

ROTATION_STREAM = 3  # BD's stream of the rotational noise (rpyfmm/bd/rotation_sampling.hpp)


def grand_dense(op) -> np.ndarray:
    """[U; W] = M [F; T] as a (6N, 6N) matrix, rows and columns [translation; rotation]."""
    n = 3 * op.size
    m = np.empty((2 * n, 2 * n))
    for col in range(2 * n):
        load = np.zeros(2 * n)
        load[col] = 1.0
        u, w = op.apply(load[:n], load[n:])
        m[:, col] = np.concatenate([u, w])
    return m


def principal_sqrt(m: np.ndarray) -> np.ndarray:
    lam, v = np.linalg.eigh(0.5 * (m + m.T))
    return (v * np.sqrt(lam)) @ v.T


def test_sample_against_dense_scaled_root():
    n = 12
    rng = np.random.default_rng(3)
    x = suspension(n, seed=4)
    a = rng.uniform(0.6, 1.4, n)
    op = rpyfmm.DirectRpy(viscosity=0.9)
    op.set_positions(x, a)
    assert op.supports_rotation
    s = np.concatenate([np.ones(3 * n), np.repeat(a, 3)])  # S = diag(I, a_i I)
    b = principal_sqrt(s[:, None] * grand_dense(op) * s[None, :]) / s[:, None]  # S^{-1} (S M S)^{1/2}
    zt, zr = rng.standard_normal((n, 3)), rng.standard_normal((n, 3))
    want = b @ np.concatenate([zt.ravel(), zr.ravel()])
    for method, tol, bound in [("lanczos", 1e-6, 1e-5), ("chebyshev", 1e-6, 1e-5), ("eigen", 1e-3, 1e-12)]:
        wt, wr, report = op.apply_sqrt_rotation(zt, zr, method=method, tolerance=tol)
        assert wt.shape == wr.shape == (n, 3)
        assert report.method == method
        got = np.concatenate([wt.ravel(), wr.ravel()])
        assert rel_err(s * got, s * want) <= bound, method  # the norm the tolerance refers to
    # The block preconditioner: another root B' (B' B'^T = M) in the same covariance; its report counts blocks.
    wt, wr, report = op.apply_sqrt_rotation(zt, zr, preconditioner="block", preconditioner_block=4)
    assert report.preconditioner_blocks >= 3
    # Shapes follow z: (3N,) in, (3N,) out.
    wt_flat, wr_flat, _ = op.apply_sqrt_rotation(zt.ravel(), zr.ravel(), method="eigen")
    assert wt_flat.shape == (3 * n,)
    np.testing.assert_allclose(np.concatenate([wt_flat, wr_flat]), want, rtol=0, atol=1e-12 * np.abs(want).max())


def test_sample_angular_equals_cli(cli, save_npy, tmp_path):
    n = 30
    x = suspension(n, seed=8)
    cli("sample", "--positions", save_npy("X.npy", x), "--radius", "1.3", "--seed", "7", "--step", "4",
        "--angular", "--sqrt-tolerance", "1e-6", "--out", tmp_path / "W.npy")
    op = rpyfmm.DirectRpy()
    op.set_positions(x, 1.3)
    zt = rpyfmm.normal_noise(n, seed=7, step=4)
    zr = rpyfmm.normal_noise(n, seed=7, step=4, stream=ROTATION_STREAM)
    wt, wr, _ = op.apply_sqrt_rotation(zt, zr, tolerance=1e-6)
    np.testing.assert_array_equal(np.load(tmp_path / "W.npy"), np.hstack([wt, wr]))


def test_free_draining_is_exact():
    eta = 1.7
    a = np.array([0.5, 1.0, 2.0])
    op = rpyfmm.FreeDraining(viscosity=eta)
    op.set_positions(np.arange(9.0).reshape(3, 3) * 3.0, a)
    assert op.supports_rotation
    zt, zr = rpyfmm.normal_noise(3, seed=1), rpyfmm.normal_noise(3, seed=1, stream=ROTATION_STREAM)
    wt, wr, report = op.apply_sqrt_rotation(zt, zr, method="lanczos")
    assert report.method == "cholesky" and report.operator_applications == 0
    np.testing.assert_allclose(wt, zt / np.sqrt(6 * np.pi * eta * a)[:, None], rtol=4e-16, atol=0)
    np.testing.assert_allclose(wr, zr / np.sqrt(8 * np.pi * eta * a**3)[:, None], rtol=4e-16, atol=0)


def test_refusals():
    x = suspension(8, seed=2)
    z = np.ones((8, 3))
    pse = rpyfmm.PseRpy(box=40.0)
    pse.set_positions(x, 1.0)
    # PSE samples the grand mobility by its split sampler (docs/theory/pse.md section 5).
    assert pse.supports_rotation
    wt, wr, report = pse.apply_sqrt_rotation(z, z)
    assert report.method == "split" and wt.shape == (8, 3) and wr.shape == (8, 3)
    assert np.all(np.isfinite(wt)) and np.all(np.isfinite(wr))
    op = rpyfmm.DirectRpy()
    op.set_positions(x, 1.0)
    with pytest.raises(rpyfmm.InvalidInputError, match="z_rotation has shape"):
        op.apply_sqrt_rotation(z, z[:7])
    bad = z.copy()
    bad[3, 1] = np.nan
    with pytest.raises(rpyfmm.InvalidInputError, match="rotational noise entry \\(3, 1\\) is NaN"):
        op.apply_sqrt_rotation(z, bad)
    with pytest.raises(rpyfmm.NotSupportedError, match="split"):
        op.apply_sqrt_rotation(z, z, method="split")
