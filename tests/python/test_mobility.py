"""Mobility operators from Python: equal to the CLI, FMM within tolerance of the
direct sum, dense matrix symmetric positive definite, PSE periodic
self-mobility (Hasimoto), shapes, dtypes, no copies, GIL released."""

from __future__ import annotations

import threading
import time
import tracemalloc

import numpy as np
import pytest

import rpyfmm
from conftest import rel_err, suspension

N = 300


@pytest.fixture(scope="module")
def system() -> tuple[np.ndarray, np.ndarray]:
    x = suspension(N, seed=11)
    f = np.random.default_rng(4).standard_normal((N, 3))
    return x, f


@pytest.mark.parametrize("method,extra,factory", [
    ("direct", [], lambda: rpyfmm.make_mobility("direct")),
    ("fmm", ["--tolerance", "1e-6"], lambda: rpyfmm.make_mobility("fmm", tolerance=1e-6)),
    ("pse", ["--tolerance", "1e-4", "--box", "20"], lambda: rpyfmm.make_mobility("pse", tolerance=1e-4, box=20.0)),
])
def test_apply_equals_cli(system, cli, save_npy, tmp_path, method, extra, factory):
    x, f = system
    cli("mobility", "--positions", save_npy("X.npy", x), "--forces", save_npy("F.npy", f), "--radius", "1",
        "--method", method, *extra, "--out", tmp_path / "U.npy")
    op = factory()
    assert op.name == method
    op.set_positions(x, 1.0)
    np.testing.assert_array_equal(op.apply(f), np.load(tmp_path / "U.npy"))


def test_per_particle_radii_equal_cli(system, cli, save_npy, tmp_path):
    x, f = system
    radii = np.random.default_rng(8).uniform(0.5, 1.2, N)
    cli("mobility", "--positions", save_npy("X.npy", x), "--forces", save_npy("F.npy", f), "--radii",
        save_npy("A.npy", radii), "--method", "direct", "--out", tmp_path / "U.npy")
    op = rpyfmm.DirectRpy()
    op.set_positions(x, radii)
    assert not op.equal_radii
    np.testing.assert_array_equal(op.apply(f), np.load(tmp_path / "U.npy"))
    np.testing.assert_array_equal(op.radii, radii)


@pytest.mark.parametrize("tol", [1e-3, 1e-6, 1e-9])
def test_fmm_meets_tolerance(system, tol):
    x, f = system
    direct, fmm = rpyfmm.DirectRpy(viscosity=2.0), rpyfmm.FmmRpy(viscosity=2.0, tolerance=tol)
    radii = np.random.default_rng(1).uniform(0.3, 1.0, N)
    for op in (direct, fmm):
        op.set_positions(x, radii)
    assert rel_err(fmm.apply(f), direct.apply(f)) <= tol


def test_self_mobility_units():
    op = rpyfmm.DirectRpy(viscosity=0.7)
    op.set_positions(np.zeros((1, 3)), 1.3)
    u = op.apply(np.array([[1.0, 0.0, 0.0]]))
    np.testing.assert_allclose(u[0], [1.0 / (6 * np.pi * 0.7 * 1.3), 0.0, 0.0], rtol=1e-15)


@pytest.mark.parametrize("name", ["direct", "fmm", "pse"])
def test_dense_from_products_is_spd(name):
    n = 24
    x = suspension(n, seed=2, spacing=2.1, jitter=0.5)  # includes overlapping pairs
    op = {"direct": lambda: rpyfmm.DirectRpy(),
          "fmm": lambda: rpyfmm.FmmRpy(tolerance=1e-9),
          "pse": lambda: rpyfmm.PseRpy(box=12.0, tolerance=1e-5, wave_precision="double")}[name]()
    op.set_positions(x, 1.0)
    m = op.assemble_dense()
    assert m.shape == (3 * n, 3 * n)
    # The same matrix from Python products with the unit vectors (one block call).
    np.testing.assert_allclose(op.apply_block(np.eye(3 * n)).T, m, rtol=0, atol=1e-14 * np.abs(m).max())
    asym = np.abs(m - m.T).max() / np.abs(m).max()
    assert asym <= (1e-6 if name == "fmm" else 1e-14)
    assert np.linalg.eigvalsh(0.5 * (m + m.T)).min() > 0.0


@pytest.mark.parametrize("a_over_l", [0.02, 0.05, 0.1])
def test_pse_periodic_self_mobility_is_hasimoto(a_over_l):
    a, eta = 1.0, 1.3
    box = a / a_over_l
    op = rpyfmm.PseRpy(box=box, viscosity=eta, tolerance=1e-6)
    op.set_positions(np.array([[0.3, 0.4, 0.5]]) * box, a)
    u = op.apply(np.array([0.0, 0.0, 1.0]))
    phi = a_over_l
    hasimoto = (1.0 - 2.837297 * phi + 4.0 * np.pi / 3.0 * phi**3) / (6.0 * np.pi * eta * a)
    assert abs(u[2] - hasimoto) <= 1e-5 * hasimoto
    assert abs(u[0]) + abs(u[1]) <= 1e-6 * hasimoto
    assert op.periodic and op.box == (box, box, box)
    assert op.parameters["xi"] > 0


def test_pse_fft_measure_matches_estimate(system):
    x, f = system
    box = (np.ptp(x, axis=0) + 8.0).tolist()
    ops = [rpyfmm.PseRpy(box=box, tolerance=1e-5, fft_measure=m, wave_precision="double") for m in (False, True)]
    for op in ops:
        op.set_positions(x, 1.0)
    u0, u1 = (op.apply(f) for op in ops)
    assert np.linalg.norm(u1 - u0) <= 1e-12 * np.linalg.norm(u0)


def test_pse_wave_precision(system):
    # Single-precision wave grids (the automatic choice at tolerance >= 1e-5) against double ones:
    # float round-off only (~1e-7 relative, tests/pse/test_pse_precision.cpp); bad names refused.
    x, f = system
    box = (np.ptp(x, axis=0) + 8.0).tolist()
    auto, single, double = (rpyfmm.PseRpy(box=box, tolerance=1e-4, wave_precision=w)
                            for w in ("auto", "single", "double"))
    for op in (auto, single, double):
        op.set_positions(x, 1.0)
    assert auto.parameters["wave_precision"] == "single"
    assert double.parameters["wave_precision"] == "double"
    np.testing.assert_array_equal(auto.apply(f), single.apply(f))
    assert 0.0 < rel_err(single.apply(f), double.apply(f)) <= 1e-6
    with pytest.raises(rpyfmm.Error, match="wave precision"):
        rpyfmm.PseRpy(box=box, wave_precision="half")


def test_pse_real_space_cache():
    # The pair cache (float here, with float wave grids) against the same operator without it:
    # rounding of the kept blocks only (tests/pse/test_pse_pair_cache.cpp). After set_positions
    # the first product leaves it alone (one M F per positions), the second fills it, the third
    # reads it.
    rng = np.random.default_rng(3)
    box = 30.0
    x = rng.uniform(0.0, box, size=(1500, 3))
    f = rng.standard_normal((1500, 3))
    with_cache, without = (rpyfmm.PseRpy(box=box, tolerance=1e-3, xi=0.6, real_space_cache=c) for c in (True, False))
    for op in (with_cache, without):
        op.set_positions(x, 1.0)
    assert without.parameters["real_space_cache_bytes"] == 0
    u = without.apply(f)
    for _ in range(3):
        assert rel_err(with_cache.apply(f), u) <= 1e-6
    assert with_cache.parameters["real_space_cache_bytes"] > 0
    assert "pair cache" in with_cache.parameters["summary"]


def test_shapes_and_dtypes(system):
    x, f = system
    op = rpyfmm.DirectRpy()
    op.set_positions(x.reshape(-1), 1.0)
    u = op.apply(f)
    flat = op.apply(f.reshape(-1))
    assert flat.shape == (3 * N,) and u.shape == (N, 3)
    np.testing.assert_array_equal(flat, u.reshape(-1))
    u32 = op.apply(f.astype(np.float32))
    assert u32.dtype == np.float64
    np.testing.assert_array_equal(u32, op.apply(f.astype(np.float32).astype(np.float64)))
    np.testing.assert_array_equal(op.apply(f.tolist()), u)  # anything NumPy reads
    np.testing.assert_array_equal(op.apply(np.asfortranarray(f)), u)  # strided: converted
    assert np.array_equal(op.divergence(), np.zeros((N, 3)))


def test_out_is_written_in_place(system):
    x, f = system
    op = rpyfmm.FmmRpy(tolerance=1e-6)
    assert op.stats() == {}  # no tree before set_positions
    op.set_positions(x, 1.0)
    assert op.stats()["leaves"] >= 1 and op.stats()["leaf_capacity"] > 0
    out = np.empty((N, 3))
    address = out.ctypes.data
    result = op.apply(f, out=out)
    assert result is out and result.ctypes.data == address
    np.testing.assert_array_equal(out, op.apply(f))
    flat_out = np.empty(3 * N)
    assert op.apply(f, out=flat_out) is flat_out  # any shape with 3N entries


def test_float64_inputs_are_views_not_copies():
    a = np.random.default_rng(0).standard_normal((1000, 3))
    assert rpyfmm._rpyfmm._input_address(a) == a.ctypes.data  # used in place
    assert rpyfmm._rpyfmm._input_address(a.astype(np.float32)) != a.ctypes.data
    strided = a[::2]
    assert rpyfmm._rpyfmm._input_address(strided) != strided.ctypes.data  # converted (documented)


def test_large_arrays_are_not_copied():
    """NumPy allocations are traced by tracemalloc: apply(F, out=U) on 2.4 MB
    arrays must not allocate anything of that size in the binding layer."""
    n = 100_000
    op = rpyfmm.FreeDraining()
    x = np.random.default_rng(0).uniform(0, 100, (n, 3))
    op.set_positions(x, 1.0)
    f, u = np.ones((n, 3)), np.empty((n, 3))
    op.apply(f, out=u)  # warm-up (imports, caches)
    tracemalloc.start()
    try:
        op.apply(f, out=u)
        _, peak_view = tracemalloc.get_traced_memory()
        tracemalloc.reset_peak()
        op.apply(f.astype(np.float32), out=u)
        _, peak_copy = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak_view < f.nbytes // 20
    assert peak_copy >= f.nbytes  # the float32 conversion does copy (documented)
    np.testing.assert_allclose(u, 1.0 / (6 * np.pi))


def test_make_mobility_by_name():
    assert isinstance(rpyfmm.make_mobility("auto", 10), rpyfmm.DirectRpy)
    assert isinstance(rpyfmm.make_mobility("auto", 5000), rpyfmm.FmmRpy)
    assert isinstance(rpyfmm.make_mobility("auto", 10, box=30.0), rpyfmm.PseRpy)
    c = rpyfmm.default_fmm_crossover(1e-6)
    assert c > rpyfmm.default_fmm_crossover(1e-3)
    assert isinstance(rpyfmm.make_mobility("auto", c - 1, tolerance=1e-6), rpyfmm.DirectRpy)
    assert isinstance(rpyfmm.make_mobility("auto", c, tolerance=1e-6), rpyfmm.FmmRpy)
    assert isinstance(rpyfmm.make_mobility("auto", 200, fmm_crossover=200), rpyfmm.FmmRpy)
    assert isinstance(rpyfmm.make_mobility("none"), rpyfmm.FreeDraining)
    for op in (rpyfmm.DirectRpy(), rpyfmm.FmmRpy(), rpyfmm.PseRpy(box=(10, 12, 14))):
        assert isinstance(op, rpyfmm.MobilityOperator)


def test_make_mobility_device():
    """device='cuda' is for the PSE operator on a GPU: other methods refuse it by name, and
    without a usable device (or in a build without CUDA, as pip's) so does pse."""
    assert isinstance(rpyfmm.make_mobility("pse", box=20.0, device="cpu"), rpyfmm.PseRpy)
    with pytest.raises(rpyfmm.Error, match="no CUDA version"):
        rpyfmm.make_mobility("direct", device="cuda")
    with pytest.raises(rpyfmm.Error, match="unknown device 'gpu'"):
        rpyfmm.make_mobility("pse", box=20.0, device="gpu")
    if not rpyfmm.cuda_device_available():
        with pytest.raises(rpyfmm.Error, match="no usable CUDA device"):
            rpyfmm.make_mobility("pse", box=20.0, device="cuda")
    else:
        assert rpyfmm.make_mobility("pse", box=20.0, device="cuda").name == "pse-cuda"


def test_gil_released_during_apply():
    """While another thread is inside apply, this thread keeps running Python: the
    longest pause between its loop iterations stays far below one apply (~0.1 s)."""
    n = 8000
    op = rpyfmm.DirectRpy()
    op.set_positions(suspension(n, seed=1), 1.0)
    f = np.ones((n, 3))
    old = rpyfmm.get_num_threads()
    rpyfmm.set_num_threads(1)  # in this thread only: apply below runs in the worker thread
    try:
        start = time.perf_counter()
        op.apply(f)
        one_apply = time.perf_counter() - start
        done = threading.Event()

        def work() -> None:
            rpyfmm.set_num_threads(1)
            for _ in range(2):
                op.apply(f)
            done.set()

        t = threading.Thread(target=work)
        t.start()
        last, max_gap = time.perf_counter(), 0.0
        while not done.is_set():
            now = time.perf_counter()
            max_gap, last = max(max_gap, now - last), now
        t.join()
    finally:
        rpyfmm.set_num_threads(old)
    assert one_apply > 0.02
    assert max_gap < 0.5 * one_apply, (max_gap, one_apply)


def test_apply_with_torques_gives_the_grand_mobility():
    # Two spheres 5 apart (far field): W_0 = (F_1 x e) / (8 pi eta r^2) (half the stokeslet's vorticity),
    # U_0 = (T_1 x e) / (8 pi eta r^2) (the rotlet), W_0 += -(T_1 - 3 e (e . T_1)) / (16 pi eta r^3); the
    # self blocks 1/(6 pi eta a) and 1/(8 pi eta a^3). Forces alone give apply(F).
    eta, a, r = 1.5, 1.0, 5.0
    x = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, -r]])
    e = np.array([0.0, 0.0, 1.0])  # x_0 - x_1, normalized
    F = np.array([[0.0, 0.0, 0.0], [1.0, 0.5, -0.25]])
    T = np.array([[0.0, 0.0, 0.0], [0.3, -0.2, 0.7]])
    op = rpyfmm.DirectRpy(viscosity=eta)
    op.set_positions(x, a)
    assert op.supports_rotation
    U, W = op.apply(F, T)
    tt = (np.eye(3) * (1 + 2 * a * a / (3 * r * r)) + np.outer(e, e) * (1 - 2 * a * a / (r * r))) / (8 * np.pi * eta * r)
    want_u = tt @ F[1] + np.cross(T[1], e) / (8 * np.pi * eta * r * r)
    want_w = np.cross(F[1], e) / (8 * np.pi * eta * r * r) - (T[1] - 3 * e * (e @ T[1])) / (16 * np.pi * eta * r**3)
    np.testing.assert_allclose(U[0], want_u, rtol=1e-14, atol=1e-17)
    np.testing.assert_allclose(W[0], want_w, rtol=1e-14, atol=1e-17)
    np.testing.assert_allclose(W[1], T[1] / (8 * np.pi * eta * a**3) + np.cross(F[0], -e), rtol=1e-14, atol=1e-17)
    U0, _ = op.apply(F, np.zeros_like(T))
    np.testing.assert_allclose(U0, op.apply(F), rtol=1e-13, atol=1e-17)
    # The FMM operator's grand mobility: these two spheres are a near-field pair, summed exactly.
    fmm = rpyfmm.FmmRpy(viscosity=eta)
    fmm.set_positions(x, a)
    assert fmm.supports_rotation
    U_fmm, W_fmm = fmm.apply(F, T)
    np.testing.assert_allclose(U_fmm, U, rtol=1e-13, atol=1e-17)
    np.testing.assert_allclose(W_fmm, W, rtol=1e-13, atol=1e-17)
    # PSE: the periodic grand mobility (a large box: close to the free-space pair, not equal).
    pse = rpyfmm.PseRpy(box=20.0, viscosity=eta)
    pse.set_positions(x + 10.0, a)
    assert pse.supports_rotation
    U_pse, W_pse = pse.apply(F, T)
    assert U_pse.shape == U.shape and W_pse.shape == W.shape
    assert np.all(np.isfinite(U_pse)) and np.all(np.isfinite(W_pse))
    # W_1 is the torqued sphere's self rotation; the images change it by O(a^2 / L^2).
    np.testing.assert_allclose(W_pse[1], W[1], rtol=2e-2)
    with pytest.raises(rpyfmm.InvalidInputError, match="torques has shape"):
        op.apply(F, T[:1])
