"""Brownian samplers from Python: the Philox stream and sqrt results equal the
CLI's, M^{1/2} z against a dense NumPy eigendecomposition, reports, covariance
tests with fixed seeds (Lanczos on DirectRpy, PSE split sampler)."""

from __future__ import annotations

import numpy as np
import pytest

import rpyfmm
from conftest import cli_json, rel_err, suspension


def principal_sqrt(m: np.ndarray) -> np.ndarray:
    lam, v = np.linalg.eigh(0.5 * (m + m.T))
    return (v * np.sqrt(lam)) @ v.T


def test_normal_noise_stream():
    a = rpyfmm.normal_noise(20000, seed=5, step=3)
    assert a.shape == (20000, 3)
    np.testing.assert_array_equal(a, rpyfmm.normal_noise(20000, 5, 3))
    assert not np.array_equal(a, rpyfmm.normal_noise(20000, 5, 4))
    assert abs(a.mean()) < 5 / np.sqrt(a.size)
    assert abs(a.var() - 1.0) < 5 * np.sqrt(2.0 / a.size)
    # Particle i's values do not depend on N (counter-based).
    np.testing.assert_array_equal(rpyfmm.normal_noise(10, 5, 3), a[:10])


@pytest.mark.parametrize("method", ["lanczos", "chebyshev"])
def test_sample_equals_cli(cli, save_npy, tmp_path, method):
    n = 200
    x = suspension(n, seed=9)
    out = cli("sample", "--positions", save_npy("X.npy", x), "--radius", "1", "--seed", "7", "--step", "2",
              "--method", method, "--sqrt-tolerance", "1e-6", "--out", tmp_path / "W.npy", "--json")
    info = cli_json(out)
    op = rpyfmm.DirectRpy()
    op.set_positions(x, 1.0)
    w, report = op.apply_sqrt(rpyfmm.normal_noise(n, seed=7, step=2), method=method, tolerance=1e-6)
    np.testing.assert_array_equal(w, np.load(tmp_path / "W.npy"))
    assert report.method == info["method"] == method
    assert report.iterations == info["iterations"] > 0
    assert report.error_estimate == info["error_estimate"]
    assert info["sqrt_tolerance"] == 1e-6  # keys named as the options
    assert report.converged


def test_sqrt_against_dense_eigendecomposition():
    n = 40
    x = suspension(n, seed=3, spacing=2.1, jitter=0.5)
    op = rpyfmm.DirectRpy(viscosity=0.5)
    op.set_positions(x, np.linspace(0.6, 1.0, n))
    z = rpyfmm.normal_noise(n, seed=1)
    ref = (principal_sqrt(op.assemble_dense()) @ z.reshape(-1)).reshape(n, 3)
    w, rep = op.apply_sqrt(z, method="eigen")
    assert rel_err(w, ref) < 1e-10 and rep.method == "eigen"
    w, rep = op.apply_sqrt(z, method="lanczos", tolerance=1e-7)
    assert rel_err(w, ref) < 1e-6 and rep.error_estimate <= 1e-7 and rep.iterations > 0
    w, rep = op.apply_sqrt(z, method="chebyshev", tolerance=1e-5)
    assert rel_err(w, ref) < 1e-5 and rep.lambda_min > 0 and rep.lambda_max > rep.lambda_min
    # Cholesky gives L z, L L^T = M: not the principal root, but the right covariance.
    w, rep = op.apply_sqrt(z, method="cholesky")
    assert rep.method == "cholesky" and np.isfinite(w).all()
    bounds = rpyfmm.estimate_spectrum_bounds(op)
    lam = np.linalg.eigvalsh(op.assemble_dense())
    assert bounds.lambda_min <= lam.min() and bounds.lambda_max >= lam.max()


def test_block_preconditioned_sampler():
    """preconditioner='block': w = G^{-1} (G M G^T)^{1/2} z with G = L^{-1}, L L^T = M's block
    diagonal. What defines the sampler: its covariance B B^T = M (B column by column from the
    samples of the 3N unit vectors, each converged to 1e-10), fewer iterations than plain Lanczos,
    and the report."""
    n = 60
    x = suspension(n, seed=4, spacing=2.1, jitter=0.5)
    op = rpyfmm.DirectRpy()
    op.set_positions(x, 1.0)
    m = op.assemble_dense()
    b = np.stack([op.apply_sqrt(e.reshape(n, 3), tolerance=1e-10, preconditioner="block", preconditioner_block=16)[0]
                  .reshape(-1) for e in np.eye(3 * n)], axis=1)
    assert rel_err(b @ b.T, m) < 1e-8
    assert rel_err(b, principal_sqrt(m)) > 1e-2  # a different square root than M^{1/2}
    z = rpyfmm.normal_noise(n, seed=3)
    _, plain = op.apply_sqrt(z, tolerance=1e-6)
    _, rep = op.apply_sqrt(z, tolerance=1e-6, preconditioner="block", preconditioner_block=16)
    assert rep.preconditioner_blocks == 4 and plain.preconditioner_blocks == 0
    assert rep.iterations < plain.iterations
    _, rep = op.apply_sqrt(z, method="eigen", preconditioner="auto")  # 'auto' off Lanczos: none
    assert rep.preconditioner_blocks == 0
    _, cheb = op.apply_sqrt(z, method="chebyshev", tolerance=1e-6)
    _, pcheb = op.apply_sqrt(z, method="chebyshev", tolerance=1e-6, preconditioner="auto")
    assert pcheb.preconditioner_blocks > 0 and pcheb.iterations < cheb.iterations
    with pytest.raises(rpyfmm.Error, match="Lanczos and Chebyshev samplers only"):
        op.apply_sqrt(z, method="cholesky", preconditioner="block")
    with pytest.raises(rpyfmm.Error, match="unknown preconditioner"):
        op.apply_sqrt(z, preconditioner="jacobi")


def test_sqrt_apply_on_a_python_operator():
    rng = np.random.default_rng(2)
    a = rng.standard_normal((30, 30))
    m = a @ a.T + 30 * np.eye(30)
    z = rng.standard_normal(30)
    w, rep = rpyfmm.sqrt_apply(lambda v: m @ v, z, tolerance=1e-10)
    assert rel_err(w, principal_sqrt(m) @ z) < 1e-8 and rep.method == "lanczos"

    def broken(v: np.ndarray) -> np.ndarray:
        raise KeyError("matvec failed")

    with pytest.raises(KeyError, match="matvec failed"):
        rpyfmm.sqrt_apply(broken, z)


def covariance_z_scores(samples: np.ndarray, m: np.ndarray) -> np.ndarray:
    """|C - M| in units of the standard error of a sample covariance of K Gaussian draws,
    sqrt((M_ii M_jj + M_ij^2) / K)."""
    k = samples.shape[0]
    c = samples.T @ samples / k
    d = np.diag(m)
    return np.abs(c - m) / np.sqrt((np.outer(d, d) + m * m) / k)


def test_lanczos_covariance_equals_mobility():
    n, k = 4, 4000
    x = np.array([[0.0, 0, 0], [2.2, 0, 0], [0, 2.5, 0.3], [1.0, 1.0, 2.0]])
    op = rpyfmm.DirectRpy()
    op.set_positions(x, 1.0)
    z = np.stack([rpyfmm.normal_noise(n, seed=11, step=s) for s in range(k)])
    w, rep = op.apply_sqrt_block(z, tolerance=1e-8)
    assert w.shape == (k, n, 3) and rep.converged
    assert covariance_z_scores(w.reshape(k, -1), op.assemble_dense()).max() < 5.0


def test_pse_split_sampler_covariance_equals_mobility():
    n, k = 3, 1500
    x = np.array([[1.0, 1.0, 1.0], [3.5, 1.2, 1.0], [2.0, 4.0, 5.0]])
    op = rpyfmm.PseRpy(box=8.0, tolerance=1e-4)
    op.set_positions(x, 1.0)
    samples = np.stack([op.sample(seed=3, step=s)[0].reshape(-1) for s in range(k)])
    w1, rep = op.sample(seed=3, step=0)
    np.testing.assert_array_equal(w1.reshape(-1), samples[0])  # reproducible
    assert rep.method == "split"
    assert covariance_z_scores(samples, op.assemble_dense()).max() < 5.0
    # apply_sqrt('auto') on PSE is the split sampler: a deterministic function of z.
    z = rpyfmm.normal_noise(n, seed=1)
    np.testing.assert_array_equal(op.apply_sqrt(z)[0], op.apply_sqrt(z)[0])
