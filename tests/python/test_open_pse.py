"""PSE with open boundaries from Python (OpenPseRpy, docs/theory/pse.md section 6): products against
the exact sums of DirectRpy, the factory's choice for pse without a box, the split sampler, and a
short BD run with method 'pse' in free space."""

from __future__ import annotations

import numpy as np
import pytest

import rpyfmm
from conftest import rel_err


def _cloud(n: int, rho: float, seed: int) -> np.ndarray:
    """n points uniform in a ball of radius rho (overlapping pairs at the densities used here)."""
    rng = np.random.default_rng(seed)
    d = rng.uniform(-1.0, 1.0, size=(8 * n, 3))
    d = d[np.einsum("ij,ij->i", d, d) <= 1.0][:n]
    return rho * d


@pytest.mark.parametrize("tol", [1e-3, 1e-5])
def test_open_pse_matches_direct(tol):
    x = _cloud(200, 8.0, 1)
    f = np.random.default_rng(2).normal(0.2, 1.0, size=x.shape)
    op = rpyfmm.OpenPseRpy(tolerance=tol)
    op.set_positions(x, 1.0)
    ref = rpyfmm.DirectRpy()
    ref.set_positions(x, 1.0)
    assert rel_err(op.apply(f), ref.apply(f)) <= tol
    assert op.parameters["open_truncation"] > 16.0
    assert op.constant_part == pytest.approx(1.0 / (4.0 * np.pi * op.parameters["open_truncation"]), rel=1e-14)
    assert len(op.box) == 3


def test_factory_gives_open_pse_without_a_box():
    op = rpyfmm.make_mobility("pse", 10)
    assert isinstance(op, rpyfmm.OpenPseRpy)
    assert op.name == "pse-open"


def test_sample_is_keyed_and_finite():
    x = _cloud(50, 5.0, 3)
    op = rpyfmm.OpenPseRpy()
    op.set_positions(x, 1.0)
    w1, rep = op.sample(7, 3)
    w2, _ = op.sample(7, 3)
    w3, _ = op.sample(7, 4)
    assert w1.shape == (50, 3) and np.all(np.isfinite(w1))
    assert np.array_equal(w1, w2) and not np.array_equal(w1, w3)
    u, _ = op.apply_with_noise(np.zeros_like(x), 0.0, 1, 2)
    assert np.all(u == 0.0)


def test_bd_with_open_pse_runs():
    x = _cloud(30, 6.0, 4)
    sim = rpyfmm.Simulation(x, 1.0, mobility="pse", dt=0.01, seed=5)
    sim.run(5)
    assert np.all(np.isfinite(sim.positions))
