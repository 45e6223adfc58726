"""Laplace FMM and direct sums from Python: equal to the CLI on the same .npy
inputs, accurate against the direct sum, shapes/outputs/out= handling."""

from __future__ import annotations

import numpy as np
import pytest

import rpyfmm
from conftest import suspension


@pytest.fixture(scope="module")
def points() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(3)
    sources = rng.uniform(-1.0, 1.0, size=(1500, 3))
    charges = rng.standard_normal(1500)
    targets = rng.uniform(-1.5, 1.5, size=(200, 3))
    return sources, charges, targets


def test_direct_equals_cli(points, cli, save_npy, tmp_path):
    s, q, _ = points
    cli("laplace", "--sources", save_npy("S.npy", s), "--charges", save_npy("Q.npy", q), "--direct",
        "--out", tmp_path / "R.npy")
    np.testing.assert_array_equal(rpyfmm.laplace_direct(s, q), np.load(tmp_path / "R.npy"))


def test_fmm_equals_cli_and_meets_eps(points, cli, save_npy, tmp_path):
    s, q, t = points
    cli("laplace", "--sources", save_npy("S.npy", s), "--targets", save_npy("T.npy", t), "--charges",
        save_npy("Q.npy", q), "--tolerance", "1e-6", "--out", tmp_path / "R.npy")
    fmm = rpyfmm.LaplaceFmm(tolerance=1e-6)
    fmm.set_points(s, targets=t)
    r = fmm.evaluate(q)
    assert r.shape == (200, 10) and r.dtype == np.float64
    np.testing.assert_array_equal(r, np.load(tmp_path / "R.npy"))
    ref = rpyfmm.laplace_direct(s, q, targets=t)
    for cols in (slice(0, 1), slice(1, 4), slice(4, 10)):  # potential, gradient, Hessian separately
        assert np.linalg.norm(r[:, cols] - ref[:, cols]) <= 1e-6 * np.linalg.norm(ref[:, cols])


def test_potential_matches_numpy_sum():
    rng = np.random.default_rng(1)
    s, q = rng.uniform(size=(40, 3)), rng.standard_normal(40)
    r = rpyfmm.laplace_direct(s, q, outputs="potential")
    d = np.linalg.norm(s[:, None, :] - s[None, :, :], axis=2)
    np.fill_diagonal(d, np.inf)
    np.testing.assert_allclose(r[:, 0], (q[None, :] / d).sum(axis=1), rtol=1e-12)
    assert not r[:, 1:].any()  # unrequested columns are zero


def test_densities_outputs_and_plan_reuse(points):
    s, q, _ = points
    fmm = rpyfmm.LaplaceFmm(tolerance=1e-9)
    fmm.set_points(s.reshape(-1))  # (3N,) works too
    assert fmm.num_sources == fmm.num_targets == len(s)
    q2 = np.stack([q, 2.0 * q + 1.0])
    r2 = fmm.evaluate(q2, outputs=["potential", "gradient"])
    assert r2.shape == (2, len(s), 10)
    np.testing.assert_allclose(r2[1], fmm.evaluate(2.0 * q + 1.0, outputs="potential|gradient"), rtol=1e-12)
    assert not r2[:, :, 4:].any()
    assert rpyfmm.POTENTIAL | rpyfmm.GRADIENT == 3
    stats = fmm.stats()
    assert stats["leaves"] > 0 and stats["order"] > 0
    assert "total" in fmm.last_timings()


def test_out_written_in_place_and_float32_converted(points):
    s, q, _ = points
    out = np.empty((len(s), 10))
    r = rpyfmm.laplace_direct(s, q, out=out)
    assert r is out
    s32, q32 = s.astype(np.float32), q.astype(np.float32)
    np.testing.assert_array_equal(rpyfmm.laplace_direct(s32, q32),
                                  rpyfmm.laplace_direct(s32.astype(np.float64), q32.astype(np.float64)))


def test_fmm_results_independent_of_threads():
    x = suspension(800, seed=5)
    q = np.random.default_rng(2).standard_normal(800)
    fmm = rpyfmm.LaplaceFmm(tolerance=1e-6)
    fmm.set_points(x)
    old = rpyfmm.get_num_threads()
    try:
        rpyfmm.set_num_threads(1)
        assert rpyfmm.get_num_threads() == 1
        one = fmm.evaluate(q)
        rpyfmm.set_num_threads(2)
        two = fmm.evaluate(q)
    finally:
        rpyfmm.set_num_threads(old)
    np.testing.assert_array_equal(one, two)


def test_fitted_leaf_grid_from_python():
    # 8e3 uniform points at ~27 per leaf: k = round(cbrt(8000 / 27)) = 7 boxes per side at level 3,
    # root 8/7 of the bounding cube, capacity 54; the FMM on that grid still meets eps.
    rng = np.random.default_rng(4)
    x = rng.uniform(0.0, 1.0, size=(8000, 3))
    q = rng.standard_normal(8000)
    capacity, root_scale = rpyfmm.fit_leaf_grid(x, 27)
    assert capacity == 54 and root_scale == pytest.approx(8.0 / 7.0)
    assert rpyfmm.fit_leaf_grid(x[:10], 27) is None
    with pytest.raises(rpyfmm.InvalidArgumentError, match="occupancy"):
        rpyfmm.fit_leaf_grid(x, 0)
    bad = x.copy()
    bad[3, 1] = np.nan
    with pytest.raises(rpyfmm.InvalidInputError, match="points|sources"):
        rpyfmm.fit_leaf_grid(bad, 27)
    fmm = rpyfmm.LaplaceFmm(tolerance=1e-6, leaf_capacity=capacity, root_scale=root_scale)
    fmm.set_points(x)
    stats = fmm.stats()
    assert stats["root_scale"] == pytest.approx(8.0 / 7.0) and stats["leaf_capacity"] == 54
    assert 250 <= stats["leaves"] <= 343
    assert 0.9 < stats["leaf_level_share"] <= 1.0  # level 3, but for level-2 boxes at the far edges
    partial = rpyfmm.LaplaceFmm(tolerance=1e-6, leaf_capacity=16)  # ~15.6 points per level-3 box: some split
    partial.set_points(x)
    assert 0.2 < partial.stats()["leaf_level_share"] < 0.9
    ref = rpyfmm.laplace_direct(x, q)
    res = fmm.evaluate(q)
    for c0, c1 in ((0, 1), (1, 4), (4, 10)):
        assert np.linalg.norm(res[:, c0:c1] - ref[:, c0:c1]) <= 1e-6 * np.linalg.norm(ref[:, c0:c1])
    small = rpyfmm.LaplaceFmm(tolerance=1e-6)  # 1000 points: below the fitted grid's sizes
    small.set_points(x[:1000])
    assert small.stats()["leaf_capacity"] == rpyfmm.fmm_default_leaf_capacity(1e-6)
    assert small.stats()["root_scale"] == 1.0
    with pytest.raises(rpyfmm.InvalidArgumentError, match="root_scale"):
        rpyfmm.LaplaceFmm(tolerance=1e-6, root_scale=0.5)


def test_cancelling_density_within_eps_of_its_absolute_field():
    """docs/theory/fmm.md, Sec. 7: the error of potential, gradient and Hessian is at most eps times
    the l2 norm of the density's absolute field sum_j |q_j| c_k / r^(k+1) (c = 1, 1, sqrt(6)); on
    this layout the second density's potential is 1/877 of its absolute field. At eps = 1e-3 and
    1e-6, just above the steps of the 3- and 6-digit tables, with 100-point leaves the Hessian is the
    output closest to the bound (1e-3: 0.36 eps at the AVX2 level; with the tables' own nodes and
    capped orders it was 0.75 eps, and 1.46 eps at 1e-6)."""
    rng = np.random.default_rng(17)
    s = rng.uniform(0.0, 1.0, size=(3000, 3))
    q = rng.uniform(-1.0, 1.0, size=(2, 3000))
    t = np.vstack([rng.uniform(0.95, 0.99, size=(1200, 3)), rng.uniform(-20.0, 20.0, size=(10, 3))])
    r_inv = 1.0 / np.linalg.norm(t[:, None, :] - s[None, :, :], axis=2)
    refs = [rpyfmm.laplace_direct(s, q[d], targets=t) for d in range(2)]
    for eps in (1e-3, 1e-6):
        for leaf_capacity in (0, 100):
            fmm = rpyfmm.LaplaceFmm(tolerance=eps, leaf_capacity=leaf_capacity)
            fmm.set_points(s, targets=t)
            r = fmm.evaluate(q)
            for d in range(2):
                w = np.abs(q[d])
                absolute = [r_inv @ w, r_inv**2 @ w, np.sqrt(6.0) * r_inv**3 @ w]
                for cols, a in zip((slice(0, 1), slice(1, 4), slice(4, 10)), absolute):
                    assert np.linalg.norm(r[d][:, cols] - refs[d][:, cols]) <= eps * np.linalg.norm(a)
