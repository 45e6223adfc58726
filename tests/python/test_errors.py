"""Every bad input raises a Python exception (an rpyfmm.Error subclass) whose
message names the problem; C++ messages arrive unchanged (compared with the CLI)."""

from __future__ import annotations

import numpy as np
import pytest

import rpyfmm
from test_bd import CONFIG

X = np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0], [0.0, 3.0, 0.0], [0.0, 0.0, 3.0]])


def ready(op: rpyfmm.MobilityOperator) -> rpyfmm.MobilityOperator:
    op.set_positions(X, 1.0)
    return op


def nan_positions() -> np.ndarray:
    x = X.copy()
    x[2, 1] = np.nan
    return x


def read_only(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


F = np.ones((4, 3))

CASES = [
    # (call, exception class, message fragment)
    (lambda: rpyfmm.DirectRpy(viscosity=-1.0), rpyfmm.InvalidArgumentError, "viscosity"),
    (lambda: rpyfmm.DirectRpy(box=10.0), rpyfmm.NotSupportedError, "periodic"),
    (lambda: rpyfmm.FmmRpy(box=(10, 10, 10)), rpyfmm.NotSupportedError, "periodic"),
    (lambda: rpyfmm.FmmRpy(tolerance=0.5), rpyfmm.InvalidArgumentError, "tolerance"),
    (lambda: rpyfmm.PseRpy(box=-3.0), rpyfmm.InvalidArgumentError, "box length Lx"),
    (lambda: rpyfmm.PseRpy(box=(1.0, 2.0)), rpyfmm.InvalidArgumentError, "box must be None"),
    (lambda: rpyfmm.PseRpy(box=20.0, tolerance=1e-12), rpyfmm.InvalidArgumentError, "tolerance"),
    (lambda: rpyfmm.DirectRpy().set_positions(nan_positions(), 1.0), rpyfmm.InvalidInputError,
     "positions entry (2, 1) is NaN"),
    (lambda: rpyfmm.DirectRpy().set_positions(np.ones((4, 2)), 1.0), rpyfmm.InvalidInputError,
     "positions has shape (4, 2), expected (N, 3) or (3N,)"),
    (lambda: rpyfmm.DirectRpy().set_positions(X, -1.0), rpyfmm.InvalidArgumentError, "radius"),
    (lambda: rpyfmm.DirectRpy().set_positions(X, "big"), rpyfmm.InvalidArgumentError, "radius must be a number"),
    (lambda: rpyfmm.DirectRpy().set_positions(X, np.ones(3)), rpyfmm.InvalidInputError, "radii"),
    (lambda: rpyfmm.DirectRpy().set_positions(np.zeros((0, 3)), 1.0), rpyfmm.InvalidInputError, ""),
    (lambda: rpyfmm.DirectRpy().apply(F), rpyfmm.Error, "set_positions"),
    (lambda: ready(rpyfmm.DirectRpy()).apply(np.ones((5, 3))), rpyfmm.InvalidInputError, "forces"),
    (lambda: ready(rpyfmm.DirectRpy()).apply(np.array([["a", "b", "c"]] * 4)), rpyfmm.InvalidInputError,
     "forces has dtype <U1"),
    (lambda: ready(rpyfmm.DirectRpy()).apply(F + 1j), rpyfmm.InvalidInputError, "forces has dtype complex128"),
    (lambda: ready(rpyfmm.DirectRpy()).apply(F, out=np.empty((4, 3), np.float32)), rpyfmm.InvalidInputError,
     "out must be a writable C-contiguous float64 array, got ndarray of dtype float32"),
    (lambda: ready(rpyfmm.DirectRpy()).apply(F, out=read_only(np.empty((4, 3)))), rpyfmm.InvalidInputError,
     "read-only"),
    (lambda: ready(rpyfmm.DirectRpy()).apply(F, out=np.empty((5, 3))), rpyfmm.InvalidInputError,
     "out has shape (5, 3), expected (4, 3)"),
    (lambda: ready(rpyfmm.DirectRpy()).apply(F, out=F), rpyfmm.InvalidInputError, "must not share memory"),
    (lambda: ready(rpyfmm.DirectRpy()).apply_sqrt(F, method="krylov"), rpyfmm.InvalidArgumentError,
     "unknown method 'krylov'"),
    (lambda: ready(rpyfmm.DirectRpy()).apply_sqrt(F, tolerance=2.0), rpyfmm.InvalidArgumentError, "tolerance"),
    (lambda: ready(rpyfmm.DirectRpy()).apply_sqrt(F, method="split"), rpyfmm.Error, "split"),
    (lambda: ready(rpyfmm.DirectRpy()).apply_block(F.reshape(-1)), rpyfmm.InvalidInputError,
     "expected (nrhs, N, 3) or (nrhs, 3N)"),
    (lambda: rpyfmm.make_mobility("magic"), rpyfmm.InvalidArgumentError, "magic"),
    (lambda: rpyfmm.make_mobility("pse", device="cuda"), rpyfmm.NotSupportedError, "periodic"),
    (lambda: rpyfmm.LaplaceFmm(tolerance=0.0).set_points(X), rpyfmm.InvalidArgumentError, "tolerance"),
    (lambda: rpyfmm.LaplaceFmm().evaluate(np.ones(4)), rpyfmm.InvalidInputError, "call set_points first"),
    (lambda: rpyfmm.laplace_direct(X, np.ones(4), outputs="flux"), rpyfmm.InvalidArgumentError,
     "unknown output 'flux'"),
    (lambda: rpyfmm.laplace_direct(X, np.ones(4), outputs=0), rpyfmm.InvalidArgumentError, "output"),
    (lambda: rpyfmm.laplace_direct(X, np.ones(5)), rpyfmm.InvalidInputError, "charges"),
    (lambda: rpyfmm.laplace_direct(X, np.ones((2, 2, 2))), rpyfmm.InvalidInputError,
     "charges has shape (2, 2, 2), expected (N,) or (nd, N)"),
    (lambda: rpyfmm.set_num_threads(0), rpyfmm.InvalidArgumentError, "set_num_threads: thread count must lie in [1, "),
    (lambda: rpyfmm.normal_noise(4, 1, out=np.empty(5)), rpyfmm.InvalidInputError, "out has shape (5,)"),
    (lambda: rpyfmm.sqrt_apply(lambda v: v, np.ones((2, 2))), rpyfmm.InvalidInputError, "z has shape (2, 2)"),
    (lambda: rpyfmm.parse_config("[integrator]\ndt = 0.1\n"), rpyfmm.InvalidArgumentError,
     "key 'particles' is missing"),
    (lambda: rpyfmm.parse_config(CONFIG.replace("dt = 0.002", "dt = -0.1")), rpyfmm.InvalidArgumentError,
     "integrator.dt"),
    (lambda: rpyfmm.parse_config("[nonsense]\nx = 1\n"), rpyfmm.Error, "nonsense"),
    (lambda: rpyfmm.load_config("/nonexistent/run.toml"), rpyfmm.FileError, "/nonexistent/run.toml"),
    (lambda: rpyfmm.run_bd("/nonexistent/run.toml"), rpyfmm.FileError, "/nonexistent/run.toml"),
    (lambda: rpyfmm.Simulation(X, dt=0.0), rpyfmm.InvalidArgumentError, "dt"),
    (lambda: rpyfmm.Simulation(X, dt=0.1, mobility="fast"), rpyfmm.InvalidArgumentError, "fast"),
    (lambda: rpyfmm.Simulation(X, dt=0.1, force=3), rpyfmm.InvalidArgumentError, "force must be a callable"),
    (lambda: rpyfmm.Simulation(X, dt=0.1, pair={"kind": "wca", "range": 2}), rpyfmm.InvalidArgumentError,
     "unknown pair key 'range'"),
    (lambda: rpyfmm.Simulation(X, dt=0.1, external_force=[1.0, 2.0]), rpyfmm.InvalidInputError,
     "external_force has shape (2,)"),
]


@pytest.mark.parametrize("call,cls,fragment", CASES, ids=[f"case{i}" for i in range(len(CASES))])
def test_bad_input_raises_named_error(call, cls, fragment):
    with pytest.raises(cls) as info:
        call()
    assert isinstance(info.value, rpyfmm.Error)
    assert fragment in str(info.value)
    assert info.value.code == cls.code or cls is rpyfmm.Error


def test_exception_hierarchy():
    assert issubclass(rpyfmm.Error, RuntimeError)
    assert issubclass(rpyfmm.InvalidArgumentError, ValueError)
    assert issubclass(rpyfmm.InvalidInputError, ValueError)
    assert issubclass(rpyfmm.NotSupportedError, NotImplementedError)
    assert issubclass(rpyfmm.NumericalFailureError, ArithmeticError)
    assert issubclass(rpyfmm.OutOfMemoryError, MemoryError)
    assert rpyfmm.InvalidInputError.code == "invalid_input"


def test_none_is_a_type_error():
    with pytest.raises(TypeError, match="apply"):
        ready(rpyfmm.DirectRpy()).apply(None)


def test_message_is_the_cli_message(cli, save_npy, tmp_path):
    """One valid range, one message: the CLI (stderr 'rpyfmm: error: <option>: <message>') and
    Python state the same range from the one definition (core/include/rpyfmm/core/ranges.hpp)."""
    stderr = cli("mobility", "--positions", save_npy("X.npy", X), "--forces", save_npy("F.npy", F),
                 "--radius", "1", "--method", "fmm", "--tolerance", "0.5", "--out", tmp_path / "U.npy", expect_rc=2)
    with pytest.raises(rpyfmm.InvalidArgumentError) as info:
        rpyfmm.make_mobility("fmm", tolerance=0.5)
    assert "tolerance" in str(info.value)
    assert stderr.startswith("rpyfmm: error: ") and stderr.count("\n") == 1
    tail = "must lie in [1e-12, 0.1], got 0.5"
    assert str(info.value).endswith(tail)
    assert stderr.strip().endswith(tail)
