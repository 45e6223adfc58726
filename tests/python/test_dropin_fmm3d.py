"""rpyfmm.fmm3d.lfmm3d, the fmm3dpy drop-in: the same results as rpyfmm's own LaplaceFmm
(times 1/(4 pi)), as an O(N^2) NumPy sum of the kernel 1/(4 pi r) in fmm3dpy's layouts, and as
fmm3dpy itself where it is installed; unsupported arguments and bad input raise clear errors."""

from __future__ import annotations

import importlib.metadata
import math

import numpy as np
import pytest

import rpyfmm
from rpyfmm.fmm3d import Output, lfmm3d

FIELDS = ("pot", "grad", "hess", "pottarg", "gradtarg", "hesstarg")
REQUESTS = [(1, 0), (2, 0), (3, 0), (0, 1), (0, 2), (0, 3), (3, 3), (2, 2), (1, 3), (3, 1)]


@pytest.fixture(scope="module")
def case() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """fmm3dpy layouts: sources (3, n), charges (2, n), targets (3, nt)."""
    rng = np.random.default_rng(11)
    sources = rng.uniform(-1.0, 1.0, size=(3, 600))
    charges = rng.standard_normal((2, 600))
    targets = rng.uniform(-1.5, 1.5, size=(3, 70))
    return sources, charges, targets


def numpy_laplace(sources: np.ndarray, charges: np.ndarray, points: np.ndarray) -> tuple:
    """sum_j c_j / (4 pi |x - y_j|) with its gradient and Hessian (xx, yy, zz, xy, xz, yz) at
    points (3, m), pairs at distance 0 dropped; charges (nd, n). Returns (nd, m), (nd, 3, m), (nd, 6, m)."""
    d = points[:, :, None] - sources[:, None, :]  # (3, m, n)
    r2 = np.sum(d * d, axis=0)
    inv = np.zeros_like(r2)
    np.divide(1.0, np.sqrt(r2), out=inv, where=r2 > 0)
    inv3 = inv**3
    inv5 = inv**5
    pot = charges @ inv.T
    grad = np.stack([-(charges @ (d[a] * inv3).T) for a in range(3)], axis=1)
    pairs = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)]
    hess = np.stack([charges @ (3.0 * d[a] * d[b] * inv5 - (a == b) * inv3).T for a, b in pairs], axis=1)
    c = 1.0 / (4.0 * math.pi)
    return c * pot, c * grad, c * hess


def expected_fields(sources, charges, targets, pg, pgt, nd):
    """The reference Output fields, in fmm3dpy's shapes for this nd."""
    q = charges[:nd]
    want = dict.fromkeys(FIELDS)
    for level, points, names in ((pg, sources, FIELDS[:3]), (pgt, targets, FIELDS[3:])):
        if level == 0:
            continue
        values = numpy_laplace(sources, q, points)
        for k in range(level):
            want[names[k]] = values[k] if nd > 1 else values[k][0]
    return want


def call(sources, charges, targets, pg, pgt, nd, eps=1e-10, fn=lfmm3d):
    q = charges[:nd] if nd > 1 else charges[0]
    return fn(eps=eps, sources=sources, charges=q, targets=targets if pgt else None, pg=pg, pgt=pgt, nd=nd)


@pytest.mark.parametrize("nd", [1, 2])
@pytest.mark.parametrize("pg,pgt", REQUESTS)
def test_matches_numpy_sum_of_one_over_4pi_r(case, pg, pgt, nd):
    sources, charges, targets = case
    out = call(sources, charges, targets, pg, pgt, nd)
    assert isinstance(out, Output) and out.ier == 0
    want = expected_fields(sources, charges, targets, pg, pgt, nd)
    for name in FIELDS:
        got = getattr(out, name)
        if want[name] is None:
            assert got is None, name
            continue
        assert got.shape == want[name].shape and got.dtype == np.float64, name
        err = np.linalg.norm(got - want[name]) / np.linalg.norm(want[name])
        assert err < 1e-8, (name, err)


def test_same_numbers_as_native_laplace_fmm(case):
    """The one script in both spellings: lfmm3d is LaplaceFmm's result times 1/(4 pi), bit for bit."""
    sources, charges, targets = case
    fmm = rpyfmm.LaplaceFmm(tolerance=1e-6)
    fmm.set_points(sources.T, targets=targets.T)
    native = fmm.evaluate(charges, outputs="all")  # (2, nt, 10)
    out = lfmm3d(eps=1e-6, sources=sources, charges=charges, targets=targets, pgt=3, nd=2)
    c = 1.0 / (4.0 * math.pi)
    np.testing.assert_array_equal(out.pottarg, native[..., 0] * c)
    np.testing.assert_array_equal(out.gradtarg, np.swapaxes(native[..., 1:4], 1, 2) * c)
    np.testing.assert_array_equal(out.hesstarg, np.swapaxes(native[..., 4:10], 1, 2) * c)
    fmm.set_points(sources.T)
    native = fmm.evaluate(charges[0], outputs="potential|gradient")
    out = lfmm3d(eps=1e-6, sources=sources, charges=charges[0], pg=2)
    np.testing.assert_array_equal(out.pot, native[:, 0] * c)
    np.testing.assert_array_equal(out.grad, native[:, 1:4].T * c)
    assert out.hess is None and out.pottarg is None


@pytest.mark.parametrize("nd", [1, 3])
@pytest.mark.parametrize("pg,pgt", [(1, 0), (2, 0), (3, 0), (0, 3), (2, 2), (3, 3)])
def test_matches_fmm3dpy(case, pg, pgt, nd):
    fmm3dpy = pytest.importorskip("fmm3dpy")
    sources, _, targets = case
    charges = np.random.default_rng(5).standard_normal((3, sources.shape[1]))
    # fmm3dpy 2.x (FMM3D >= 2.0) sums 1/(4 pi r); 1.0 summed 1/r.
    scale = 1.0 if int(importlib.metadata.version("fmm3dpy").split(".")[0]) >= 2 else 4.0 * math.pi
    theirs = call(sources, charges, targets, pg, pgt, nd, eps=1e-12, fn=fmm3dpy.lfmm3d)
    ours = call(sources, charges, targets, pg, pgt, nd, eps=1e-12)
    for name in FIELDS:
        a, b = getattr(theirs, name), getattr(ours, name)
        assert (a is None) == (b is None), name
        if a is not None:
            assert a.shape == b.shape, (name, a.shape, b.shape)
            assert np.linalg.norm(scale * b - a) <= 1e-9 * np.linalg.norm(a), name


def test_one_source_and_loose_eps():
    out = lfmm3d(eps=0.5, sources=np.zeros(3), charges=np.array([2.0]), targets=np.array([[1.0], [0.0], [0.0]]),
                 pg=1, pgt=2)
    assert out.pot.shape == (1,) and out.pot[0] == 0.0  # the self pair is dropped
    np.testing.assert_allclose(out.pottarg, [2.0 / (4.0 * math.pi)], rtol=1e-12)
    np.testing.assert_allclose(out.gradtarg[:, 0], [-2.0 / (4.0 * math.pi), 0.0, 0.0], rtol=1e-12, atol=1e-15)


def test_nothing_requested_returns_empty_output(case):
    sources, charges, _ = case
    out = lfmm3d(eps=1e-6, sources=sources, charges=charges[0])
    assert all(getattr(out, name) is None for name in FIELDS) and out.ier == 0


def test_dipoles_are_refused_by_name(case):
    sources, charges, _ = case
    with pytest.raises(rpyfmm.NotSupportedError, match="dipvec"):
        lfmm3d(eps=1e-6, sources=sources, charges=charges[0], dipvec=np.ones_like(sources), pg=1)
    with pytest.raises(NotImplementedError, match="dipvec"):
        lfmm3d(eps=1e-6, sources=sources, dipvec=np.ones_like(sources), pg=1)


@pytest.mark.parametrize(
    "change,match",
    [
        (dict(sources=np.zeros((600, 3))), r"sources has shape \(600, 3\), expected \(3, n\)"),
        (dict(charges=np.ones(5)), r"charges has shape \(5,\), expected \(600,\)"),
        (dict(charges=np.ones((2, 600))), r"charges has shape \(2, 600\), expected \(600,\) for nd = 1"),
        (dict(nd=3), r"expected \(nd, n\) = \(3, 600\)"),
        (dict(nd=0), "nd must be a positive integer"),
        (dict(pg=4), "pg must be 0, 1, 2 or 3"),
        (dict(pg=1.0), "pg must be 0, 1, 2 or 3"),
        (dict(pgt=1), "pgt = 1 requests outputs at the targets but targets is None"),
        (dict(eps=-1e-6), "eps must be a positive finite number"),
        (dict(eps=float("nan")), "eps must be a positive finite number"),
        (dict(charges=None), "charges is required"),
        (dict(targets=np.zeros((2, 4)), pgt=1), r"targets has shape \(2, 4\)"),
        (dict(charges=np.array(["a"] * 600)), "charges must be a real array"),
    ],
)
def test_bad_input_raises_clear_errors(case, change, match):
    sources, charges, _ = case
    kwargs = dict(eps=1e-6, sources=sources, charges=charges[0], pg=1)
    kwargs.update(change)
    with pytest.raises(rpyfmm.InvalidArgumentError, match=match):
        lfmm3d(**kwargs)


def test_non_finite_values_name_the_entry_in_fmm3dpy_layout(case):
    sources, charges, _ = case
    s = sources.copy()
    s[1, 7] = np.nan
    with pytest.raises(ValueError, match=r"sources entry \(1, 7\) is nan"):
        lfmm3d(eps=1e-6, sources=s, charges=charges[0], pg=1)
    q = charges[0].copy()
    q[3] = np.inf
    with pytest.raises(ValueError, match=r"charges entry \(3,\) is inf"):
        lfmm3d(eps=1e-6, sources=sources, charges=q, pg=1)


def test_unknown_and_positional_arguments_are_type_errors(case):
    sources, charges, _ = case
    with pytest.raises(TypeError, match="iprec"):
        lfmm3d(eps=1e-6, sources=sources, charges=charges[0], pg=1, iprec=2)
    with pytest.raises(TypeError):
        lfmm3d(1e-6, sources, charges[0])  # keyword-only, as in fmm3dpy
