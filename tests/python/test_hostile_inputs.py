"""Hostile input that used to pass without a word, or hang: each now raises an rpyfmm.Error
subclass whose message names the argument (docs/python.md, "Errors").

* sqrt options (tolerance, max_iterations, preconditioner_block) are checked for every operator,
  also those whose own sampler ignores them (PSE's split sampler, free draining's exact root);
* an explicitly empty target set is refused instead of read as "at the sources";
* fmm_default_leaf_capacity checks its tolerance as LaplaceFmm does;
* files that are not regular (a device such as /dev/zero, a directory) are refused before they
  are read, so a config or trajectory reader never reads without end;
* the pure-Python helpers refuse NaN, empty and negative input;
* an object whose __dlpack_device__() is not a (type, id) pair no longer crashes the reader.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import rpyfmm

X = np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0], [0.0, 3.0, 0.0], [0.0, 0.0, 3.0]])

OPERATORS = {
    "pse": lambda: rpyfmm.PseRpy(20.0),
    "open-pse": rpyfmm.OpenPseRpy,
    "free-draining": rpyfmm.FreeDraining,
    "direct": rpyfmm.DirectRpy,
}

BAD_SQRT_OPTIONS = [
    ({"tolerance": float("nan")}, "tolerance must lie in (0, 1), got nan"),
    ({"tolerance": -1.0}, "tolerance must lie in (0, 1), got -1"),
    ({"tolerance": 0.0}, "tolerance must lie in (0, 1), got 0"),
    ({"tolerance": 1e300}, "tolerance must lie in (0, 1), got 1e+300"),
    ({"max_iterations": -1}, "max_iterations must be >= 0"),
    ({"preconditioner_block": -1}, "preconditioner_block must be >= 0"),
]


@pytest.mark.parametrize("kind", OPERATORS)
@pytest.mark.parametrize("options,fragment", BAD_SQRT_OPTIONS, ids=lambda v: str(v))
def test_sqrt_options_are_checked_for_every_operator(kind, options, fragment):
    op = OPERATORS[kind]()
    op.set_positions(X, 0.5)
    with pytest.raises(rpyfmm.InvalidArgumentError, match=re.escape(f"sqrt_apply: {fragment}")):
        op.apply_sqrt(np.ones_like(X), **options)
    w, _ = op.apply_sqrt(np.ones_like(X))  # the defaults still sample
    assert np.all(np.isfinite(w))


@pytest.mark.parametrize("bad", [float("nan"), -1.0, 0.0, 2.0])
def test_simulation_sqrt_tolerance_is_checked_with_pse(bad):
    with pytest.raises(rpyfmm.InvalidArgumentError, match="Simulation: sqrt_tolerance must lie in"):
        rpyfmm.Simulation(X * 2, 0.5, dt=0.01, mobility="pse", box=20.0, sqrt_tolerance=bad)


@pytest.mark.parametrize("empty", [np.zeros((0, 3)), np.zeros(0)], ids=["(0,3)", "(0,)"])
def test_empty_targets_are_refused(empty):
    fmm = rpyfmm.LaplaceFmm()
    with pytest.raises(rpyfmm.InvalidInputError, match="LaplaceFmm.set_points: targets is empty"):
        fmm.set_points(X, empty)
    with pytest.raises(rpyfmm.InvalidInputError, match="laplace_direct: targets is empty"):
        rpyfmm.laplace_direct(X, np.ones(4), empty)
    # None still means "at the sources".
    assert rpyfmm.laplace_direct(X, np.ones(4), None).shape == (4, 10)


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -1.0, 0.0, 1.0])
def test_default_leaf_capacity_checks_the_tolerance(bad):
    with pytest.raises(rpyfmm.InvalidArgumentError, match=r"fmm_default_leaf_capacity: tolerance must lie in \[1e-15"):
        rpyfmm.fmm_default_leaf_capacity(bad)
    assert rpyfmm.fmm_default_leaf_capacity(1e-6) > 0


# The asan preset preloads the sanitizer's runtime into the (uninstrumented) interpreter.
UNDER_ASAN = "asan" in os.environ.get("LD_PRELOAD", "")


def refused_in_child(call: str, error: str, fragment: str) -> None:
    """Runs `call` in a fresh interpreter under a 2 GB address-space cap and a timeout, so that a
    reader that reads /dev/zero without end fails this test instead of filling the machine. Under
    AddressSanitizer the cap is left out (its shadow memory reserves terabytes of address space):
    the timeout alone stops a call that loops, and calls that could read without end are skipped."""
    cap = "" if UNDER_ASAN else "resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))"
    code = textwrap.dedent(f"""
        import resource
        {cap}
        import rpyfmm
        try:
            {call}
        except rpyfmm.{error} as e:
            print(str(e))
        """)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p), OMP_NUM_THREADS="1")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, env=env,
                          check=False)
    assert proc.returncode == 0, proc.stderr
    assert fragment in proc.stdout, proc.stdout + proc.stderr


@pytest.mark.parametrize("call,where", [
    ("rpyfmm.load_config('/dev/zero')", "load_config"),
    ("rpyfmm.run_bd('/dev/zero')", "config"),
    ("rpyfmm.read_xyz('/dev/zero')", "read_xyz"),
])
def test_devices_are_refused_before_reading(call, where):
    if UNDER_ASAN:  # a regression would read /dev/zero into memory without the address-space cap
        pytest.skip("needs the address-space cap, which AddressSanitizer rules out (the release run has it)")
    refused_in_child(call, "FileError", f"{where}: '/dev/zero' is")


def test_config_that_is_a_directory_is_a_file_error(tmp_path):
    with pytest.raises(rpyfmm.FileError, match="is a directory, expected a regular file"):
        rpyfmm.load_config(tmp_path)


def test_run_bd_refuses_an_empty_output_directory():
    config = "[particles]\nsource = \"random\"\ncount = 5\n[integrator]\ndt = 0.001\nsteps = 1\n"
    with pytest.raises(rpyfmm.InvalidArgumentError, match="output directory"):
        rpyfmm.run_bd(config, out_dir="")
    with pytest.raises(rpyfmm.Error, match="output.dir"):
        rpyfmm.run_bd(config + "[output]\ndir = \"\"\n")


def test_read_xyz_refuses_a_file_without_frames(tmp_path):
    empty = tmp_path / "empty.xyz"
    empty.write_text("\n\n")
    with pytest.raises(rpyfmm.InvalidInputError, match="holds no frame"):
        rpyfmm.read_xyz(empty)


@pytest.mark.parametrize("positions,fragment", [
    (np.full((2, 3, 3), np.nan), r"entry \(0, 0, 0\) is NaN"),
    (np.array([[[0.0, 0.0, 0.0]], [[np.inf, 0.0, 0.0]]]), r"entry \(1, 0, 0\) is infinite"),
    (np.zeros((0, 3, 3)), "expected \\(frames, N, 3\\)"),
    (np.zeros((2, 0, 3)), "expected \\(frames, N, 3\\)"),
])
def test_msd_refuses_nonfinite_and_empty_positions(positions, fragment):
    with pytest.raises(rpyfmm.InvalidInputError, match="msd: positions " + ".*" + fragment):
        rpyfmm.msd(positions)


@pytest.mark.parametrize("args,name", [
    ((float("nan"), 1.0, 1.0), "kT"),
    ((-1.0, 1.0, 1.0), "kT"),
    ((1.0, 0.0, 1.0), "viscosity"),
    ((1.0, float("inf"), 1.0), "viscosity"),
    ((1.0, 1.0, -2.0), "radius"),
])
def test_stokes_einstein_refuses_bad_scales(args, name):
    with pytest.raises(rpyfmm.InvalidArgumentError, match=f"stokes_einstein: {name} must be finite"):
        rpyfmm.stokes_einstein(*args)
    assert rpyfmm.stokes_einstein(0.0, 1.0, 1.0) == 0.0


@pytest.mark.parametrize("make", ["rpyfmm.PseRpy(20.0, xi=1e300)", "rpyfmm.OpenPseRpy(xi=1e300)",
                                  "rpyfmm.PseRpy(20.0, xi=1e5)"])
def test_huge_xi_is_refused_not_looped_on(make):
    """The real-space cutoff sampled r in steps of 0.01 / xi: with xi a = 1e300 the step vanished
    next to r and set_positions never returned (run in a child with a timeout)."""
    refused_in_child(f"{make}.set_positions([[0, 0, 0], [3, 0, 0]], 0.5)", "InvalidArgumentError",
                     "pse::real_space_cutoff: xi = ")


def test_rigid_forces_whose_norm_overflows_raise():
    """|b| overflowed to inf, every GMRES test passed (inf <= inf) and zero velocities came back."""
    bead = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    bodies = rpyfmm.RigidBodies(rpyfmm.DirectRpy())
    bodies.set_configuration(np.vstack([bead, bead + 5.0]), 0.3, [0, 3, 6])
    with pytest.raises(rpyfmm.NumericalFailureError, match="GMRES: the right-hand side's norm overflows"):
        bodies.apply(np.full((2, 6), 1e300))
    # Large but representable loads still give the scaled solution (linearity; rtol: GMRES at 1e-6).
    big, _ = bodies.apply(np.full((2, 6), 1e150))
    unit, _ = bodies.apply(np.full((2, 6), 1.0))
    np.testing.assert_allclose(big, 1e150 * unit, rtol=1e-5)


def test_langevin_noise_that_overflows_is_refused():
    from rpyfmm import libmobility

    solver = libmobility.NBody("open", "open", "open")
    solver.setParameters()
    solver.initialize(temperature=1.0, viscosity=1.0, hydrodynamicRadius=0.5)
    solver.setPositions(X)
    with pytest.raises(rpyfmm.InvalidArgumentError, match=r"LangevinVelocities: sqrt\(2 kbt / dt\) overflows"):
        solver.LangevinVelocities(5e-324, 1.0)


def test_malformed_dlpack_device_does_not_crash():
    """__dlpack_device__() returning a 1-tuple was indexed past its end (a segfault, hence the
    child process); it is now read through NumPy like any other array-like."""
    code = textwrap.dedent("""
        import numpy as np
        import rpyfmm

        class Odd:
            def __dlpack_device__(self):
                return (2,)
            def __array__(self, dtype=None, copy=None):
                return np.ones((4, 3))

        op = rpyfmm.DirectRpy()
        op.set_positions(np.arange(12.0).reshape(4, 3) * 2, 0.5)
        print(np.array_equal(op.apply(Odd()), op.apply(np.ones((4, 3)))))
        """)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p), OMP_NUM_THREADS="1")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, env=env,
                          check=False)
    assert proc.returncode == 0, f"exit code {proc.returncode}\n{proc.stderr}"
    assert proc.stdout.strip() == "True"


@pytest.mark.parametrize("device", [(2,), (), "cuda", None])
def test_libmobility_reads_objects_with_a_malformed_dlpack_device(device):
    """The drop-in indexed __dlpack_device__()'s result and raised IndexError/TypeError."""
    from rpyfmm import libmobility

    class Odd:
        def __dlpack_device__(self):
            return device

        def __array__(self, dtype=None, copy=None):
            return X.copy()

    solver = libmobility.NBody("open", "open", "open")
    solver.setParameters()
    solver.initialize(viscosity=1.0, hydrodynamicRadius=0.5)
    solver.setPositions(Odd())
    solver.setPositions(X)
    expected, _ = solver.Mdot(np.ones_like(X))
    solver.setPositions(Odd())
    np.testing.assert_array_equal(solver.Mdot(np.ones_like(X))[0], expected)
