"""Memory and thread safety of the bindings (docs/safety-python.md):

* arrays handed to Python callbacks own their memory (or keep their owner alive):
  kept past the call and past the object that made them, they still read the
  values they had, and writing into them changes no other array;
* several Python threads may call one object: calls are serialized, so results
  equal those of serial calls bitwise and a mutation racing a product never crashes;
* thread counts are bounded (set_num_threads, fft_threads);
* every failure coming from C++ is an rpyfmm.Error subclass.

Races and use-after-free may crash the interpreter instead of failing an
assertion, so those checks run in a child process (`run_isolated`).
"""

from __future__ import annotations

import gc
import os
import re
import subprocess
import sys
import textwrap
import threading

import numpy as np
import pytest

import rpyfmm
from conftest import suspension


def run_isolated(code: str, timeout: float = 240.0, **extra_env: str) -> str:
    """Runs PRELUDE + `code` in a fresh interpreter (same rpyfmm on sys.path, this environment plus
    `extra_env`); fails on a crash, a hang or a non-zero exit, returns stdout."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p), **extra_env)
    proc = subprocess.run([sys.executable, "-c", PRELUDE + textwrap.dedent(code)], capture_output=True, text=True,
                          timeout=timeout, env=env, check=False)
    assert proc.returncode == 0, f"exit code {proc.returncode}\nstdout:\n{proc.stdout}\nstderr:\n{proc.stderr}"
    return proc.stdout


# Allocations of the same size as the freed C++ buffers: freed memory is handed out again.
PRELUDE = """
import gc, threading
import numpy as np
import rpyfmm

def churn(shape, count=64):
    return [np.zeros(shape) for _ in range(count)]

def check_kept(kept, fresh):
    for name, (array, snapshot) in kept.items():
        assert np.array_equal(array, snapshot), name + " changed after its owner was freed"
        if array.flags.writeable:
            array[...] = 7.0
    assert not any(a.any() for a in fresh), "writing into a kept callback array changed another array"
    print("ok")
"""


# ---------------------------------------------------------------------------------------------
# 1. Arrays handed to callbacks


def test_force_callback_arrays_outlive_the_simulation():
    out = run_isolated("""
        n = 400
        x0 = np.stack(np.meshgrid(*[np.arange(8)] * 3, indexing="ij"), -1).reshape(-1, 3)[:n] * 3.0
        kept = {}
        def force(x, step, f):
            f += 0.5
            kept["x"] = (x, x.copy())
            kept["f"] = (f, f.copy())
        sim = rpyfmm.Simulation(x0, dt=0.01, mobility="none", force=force)
        sim.step()
        del sim
        gc.collect()
        fresh = churn((n, 3))
        check_kept(kept, fresh)
        """)
    assert out.strip() == "ok"


def test_force_callback_forces_reach_the_step():
    """The callback's arrays are copies, yet what it adds in place and what it returns both act."""
    x0 = suspension(20, seed=3, spacing=3.0)
    g = np.array([0.3, -0.2, 0.1])

    def in_place(x, step, f):
        f += g

    def returned(x, step, f):
        return np.broadcast_to(g, x.shape)

    moved = []
    for force in (in_place, returned):
        sim = rpyfmm.Simulation(x0, dt=0.1, kT=0.0, mobility="none", force=force)
        sim.step()
        np.testing.assert_array_equal(sim.last_forces, np.broadcast_to(g, x0.shape))
        moved.append(sim.positions - x0)
    mu = 1.0 / (6.0 * np.pi)  # free draining, viscosity 1, radius 1
    np.testing.assert_allclose(moved[0], 0.1 * mu * np.broadcast_to(g, x0.shape), rtol=1e-12)
    np.testing.assert_array_equal(moved[0], moved[1])


def test_sqrt_apply_matvec_argument_outlives_the_call():
    out = run_isolated("""
        n = 3000
        d = np.linspace(1.0, 2.0, n)
        kept = {}
        def matvec(v):
            kept.setdefault("first", (v, v.copy()))
            return d * v
        w, _ = rpyfmm.sqrt_apply(matvec, np.ones(n), tolerance=1e-8)
        assert np.allclose(w, np.sqrt(d), rtol=1e-6)
        gc.collect()
        fresh = churn((n,))
        check_kept(kept, fresh)
        """)
    assert out.strip() == "ok"


def test_rigid_force_function_arrays_outlive_the_dynamics():
    out = run_isolated("""
        shape = 1.5 * rpyfmm.icosphere_beads(1)
        kept = {}
        def forces(t, q, quat, beads):
            kept["q"], kept["quat"], kept["beads"] = (q, q.copy()), (quat, quat.copy()), (beads, beads.copy())
            return np.zeros((1, 6))
        sim = rpyfmm.RigidBodyDynamics(rpyfmm.DirectRpy(), shape, 0.3, [0, 42], [[0.0, 0.0, 0.0]], dt=0.01,
                                       forces=forces)
        sim.step()
        del sim
        gc.collect()
        fresh = churn((42, 3)) + churn((1, 4)) + churn((1, 3))
        check_kept(kept, fresh)
        """)
    assert out.strip() == "ok"


# ---------------------------------------------------------------------------------------------
# 2. Several Python threads on one object


def in_threads(work, count: int = 4) -> list:
    """Runs work(k) in `count` threads started together; returns their results (re-raises)."""
    results, errors = [None] * count, []
    barrier = threading.Barrier(count)

    def run(k: int) -> None:
        try:
            barrier.wait()
            results[k] = work(k)
        except BaseException as e:  # noqa: BLE001 - handed to the main thread
            errors.append(e)

    threads = [threading.Thread(target=run, args=(k,)) for k in range(count)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    if errors:
        raise errors[0]
    return results


def test_concurrent_pse_apply_equals_serial():
    n = 300
    x = suspension(n, seed=5, spacing=2.6)
    box = 2.6 * np.ceil(n ** (1 / 3)) + 1.0
    # Without the real-space cache every product after set_positions is bitwise the same (with it,
    # the first product differs from the later ones in round-off).
    op = rpyfmm.PseRpy(box=box, tolerance=1e-4, real_space_cache=False)
    op.set_positions(x, 1.0)
    forces = [np.random.default_rng(k).standard_normal((n, 3)) for k in range(4)]
    serial = [op.apply(f) for f in forces]
    for _ in range(3):
        got = in_threads(lambda k: [op.apply(forces[k]) for _ in range(3)])
        for k in range(4):
            for u in got[k]:
                np.testing.assert_array_equal(u, serial[k])


def test_set_positions_racing_apply_never_crashes():
    """One thread alternates two configurations while three apply: every product is the
    product of one of the two configurations, bitwise (FmmRpy, DirectRpy, PseRpy, LaplaceFmm)."""
    out = run_isolated("""
        n = 1500
        rng = np.random.default_rng(2)
        xs = [rng.uniform(0, 40, (n, 3)), rng.uniform(0, 40, (n, 3))]
        f = rng.standard_normal((n, 3))
        makers = {"fmm": lambda: rpyfmm.FmmRpy(tolerance=1e-4), "direct": lambda: rpyfmm.DirectRpy(),
                  "pse": lambda: rpyfmm.PseRpy(box=40.0, tolerance=1e-3, real_space_cache=False)}
        for name, make in makers.items():
            expected = []
            for x in xs:
                ref = make(); ref.set_positions(x, 0.5); expected.append(ref.apply(f))
            op = make(); op.set_positions(xs[0], 0.5)
            bad, stop = [], threading.Event()
            def mutate():
                for i in range(12):
                    op.set_positions(xs[i % 2], 0.5)
                stop.set()
            def apply():
                while not stop.is_set():
                    u = op.apply(f)
                    if not any(np.array_equal(u, e) for e in expected):
                        bad.append(name)
            threads = [threading.Thread(target=mutate)] + [threading.Thread(target=apply) for _ in range(3)]
            for t in threads: t.start()
            for t in threads: t.join()
            assert not bad, bad
        q = rng.standard_normal(n)
        expected = []
        for x in xs:
            ref = rpyfmm.LaplaceFmm(eps=1e-5); ref.set_points(x); expected.append(ref.evaluate(q))
        fmm = rpyfmm.LaplaceFmm(eps=1e-5); fmm.set_points(xs[0])
        bad, stop = [], threading.Event()
        def mutate():
            for i in range(12):
                fmm.set_points(xs[i % 2])
            stop.set()
        def evaluate():
            while not stop.is_set():
                r = fmm.evaluate(q)
                if not any(np.array_equal(r, e) for e in expected):
                    bad.append("laplace")
        threads = [threading.Thread(target=mutate)] + [threading.Thread(target=evaluate) for _ in range(3)]
        for t in threads: t.start()
        for t in threads: t.join()
        assert not bad, bad
        print("ok")
        """)
    assert out.strip() == "ok"


def test_concurrent_simulation_steps_equal_serial_steps():
    """Steps from four threads are serialized: 4 x 5 steps equal 20 steps in one thread, bitwise."""
    x0 = suspension(60, seed=8, spacing=2.8)

    def push(x, step, f) -> None:
        f[:, 2] += 0.01

    def make() -> rpyfmm.Simulation:
        return rpyfmm.Simulation(x0, dt=0.002, seed=3, mobility="direct", pair="wca", force=push)

    serial = make()
    serial.run(20)
    shared = make()
    in_threads(lambda k: [shared.step() for _ in range(5)])
    assert shared.step_count == 20
    np.testing.assert_array_equal(shared.positions, serial.positions)


def test_concurrent_rigid_bodies_and_their_operator():
    """RigidBodies.apply from several threads, while others use its bead operator directly:
    each solve equals the serial one bitwise."""
    shell = 2.0 * rpyfmm.icosphere_beads(1)
    a = 2.0 * rpyfmm.icosphere_bead_radius(1)
    beads = np.vstack([shell, shell + [6.0, 0.0, 0.0]])
    op = rpyfmm.DirectRpy()
    bodies = rpyfmm.RigidBodies(op, tolerance=1e-8)
    bodies.set_configuration(beads, a, [0, 42, 84])
    ft = np.random.default_rng(1).standard_normal((2, 6))
    f = np.ones((84, 3))
    expected_bodies, expected_beads = bodies.apply(ft)[0], op.apply(f)
    got = in_threads(lambda k: [bodies.apply(ft)[0] if k % 2 else op.apply(f) for _ in range(3)])
    for k, results in enumerate(got):
        for r in results:
            np.testing.assert_array_equal(r, expected_bodies if k % 2 else expected_beads)


def test_concurrent_rigid_dynamics_steps_equal_serial_steps():
    """RigidBodyDynamics steps from three threads (GIL released, noise keyed by the step number)
    equal the same number of steps in one thread, bitwise."""
    shape = 1.5 * rpyfmm.icosphere_beads(1)
    a = 1.5 * rpyfmm.icosphere_bead_radius(1)

    def make(forces=None) -> rpyfmm.RigidBodyDynamics:
        return rpyfmm.RigidBodyDynamics(rpyfmm.DirectRpy(), np.vstack([shape, shape]), a, [0, 42, 84],
                                        [[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]], dt=0.01, seed=2, forces=forces)

    def push(t, q, quat, beads):
        return np.tile([0.1, 0.0, 0.0, 0.0, 0.0, 0.05], (2, 1))

    for forces in (None, push):
        serial = make(forces)
        serial.run(6)
        shared = make(forces)
        in_threads(lambda k: [shared.step() for _ in range(2)], count=3)
        assert shared.step_count == 6
        np.testing.assert_array_equal(shared.positions, serial.positions)
        np.testing.assert_array_equal(shared.orientations, serial.orientations)


def test_force_function_using_the_bead_operator_raises():
    """The bead operator is in use during a RigidBodyDynamics step: its apply from the force
    function raises NotSupportedError (not a deadlock); reading its size works."""
    out = run_isolated("""
        shape = 1.5 * rpyfmm.icosphere_beads(1)
        op = rpyfmm.DirectRpy()
        seen = []
        def forces(t, q, quat, beads):
            seen.append(op.size)
            op.apply(np.ones((42, 3)))
            return np.zeros((1, 6))
        sim = rpyfmm.RigidBodyDynamics(op, shape, 0.3, [0, 42], [[0.0, 0.0, 0.0]], dt=0.01, forces=forces)
        try:
            sim.step()
        except rpyfmm.NotSupportedError as e:
            assert "callback" in str(e) and "MobilityOperator.apply" in str(e), str(e)
            print("raised", seen)
        """, timeout=60)
    assert out.strip() == "raised [42]"


def test_callback_calling_its_own_simulation_raises():
    """A force callback may read its Simulation; stepping it from inside raises (no deadlock)."""
    out = run_isolated("""
        seen = {}
        def force(x, step, f):
            seen["positions"] = sim.positions.copy()
            seen["count"] = sim.step_count
            sim.step()
        sim = rpyfmm.Simulation(np.array([[0.0, 0, 0], [4.0, 0, 0]]), dt=0.01, mobility="none", force=force)
        try:
            sim.step()
        except rpyfmm.Error as e:
            assert "callback" in str(e), str(e)
            print("raised", type(e).__name__)
        assert seen["count"] == 0 and np.array_equal(seen["positions"], [[0.0, 0, 0], [4.0, 0, 0]])
        """, timeout=60)
    assert out.strip() == "raised NotSupportedError"


# ---------------------------------------------------------------------------------------------
# 3. Thread counts


def test_thread_counts_are_bounded():
    old = rpyfmm.get_num_threads()
    try:
        for bad in (0, -1, 100000):
            with pytest.raises(rpyfmm.InvalidArgumentError, match="set_num_threads: thread count must lie in"):
                rpyfmm.set_num_threads(bad)
        assert rpyfmm.get_num_threads() == old
        rpyfmm.set_num_threads(1)
        assert rpyfmm.get_num_threads() == 1
    finally:
        rpyfmm.set_num_threads(old)
    for bad in (-1, 100000):
        with pytest.raises(rpyfmm.InvalidArgumentError, match="fft_threads"):
            rpyfmm.PseRpy(box=20.0, fft_threads=bad)
    for good in (0, 1):
        rpyfmm.PseRpy(box=20.0, fft_threads=good).set_positions(suspension(10), 1.0)


# ---------------------------------------------------------------------------------------------
# 4. Errors


def test_checkpoint_that_is_a_directory_is_a_file_error(tmp_path):
    with pytest.raises(rpyfmm.FileError, match=re.escape(str(tmp_path))):
        rpyfmm.restart_bd(tmp_path)


def test_read_xyz_errors_name_the_file(tmp_path):
    binary = tmp_path / "binary.xyz"
    binary.write_bytes(bytes(range(256)))
    with pytest.raises(rpyfmm.InvalidInputError, match="binary.xyz"):
        rpyfmm.read_xyz(binary)
    truncated = tmp_path / "truncated.xyz"
    truncated.write_text("3\nTime=0 Step=0\nA 0 0 0\n")
    with pytest.raises(rpyfmm.InvalidInputError, match="truncated.xyz"):
        rpyfmm.read_xyz(truncated)
    with pytest.raises(rpyfmm.FileError, match="missing.xyz"):
        rpyfmm.read_xyz(tmp_path / "missing.xyz")
    with pytest.raises(rpyfmm.InvalidInputError, match=r"msd: positions has shape \(3,\)"):
        rpyfmm.msd(np.zeros(3))


@pytest.mark.parametrize("make", [rpyfmm.DirectRpy, rpyfmm.FmmRpy, lambda **kw: rpyfmm.PseRpy(box=20.0, **kw)],
                         ids=["direct", "fmm", "pse"])
def test_huge_forces_give_the_scaled_product_or_raise(make):
    op = make()
    x = np.array([[1.0, 1.0, 1.0], [4.0, 1.0, 1.0]])
    op.set_positions(x, 1.0)
    f = np.array([[1.0, 0.5, 0.0], [1.0, 0.0, -0.25]])
    reference = op.apply(f)
    # M is linear: forces near 1e308 or 1e-300 give the scaled product (PSE's grids are single
    # precision at its default tolerance; the direct pair terms d (d . F) overflowed at 1e308). The
    # scales are powers of two, so the products are the reference's exactly.
    for e in (1020, -1000):
        np.testing.assert_array_equal(np.ldexp(op.apply(np.ldexp(f, e)), -e), reference)
    op = make(viscosity=1e-3)  # M F ~ 1e308 / (6 pi 1e-3) overflows: raised, never returned
    op.set_positions(x, 1.0)
    with pytest.raises(rpyfmm.NumericalFailureError, match=r"apply: velocities entry \(0, 0\) is infinite"):
        op.apply(np.full((2, 3), 1e308))


STD_EXCEPTIONS = [
    # (C++ exception thrown by rpyfmm._rpyfmm._throw, Python class, also a subclass of)
    ("bad_alloc", rpyfmm.OutOfMemoryError, MemoryError),
    ("length_error", rpyfmm.OutOfMemoryError, MemoryError),
    ("filesystem_error", rpyfmm.FileError, rpyfmm.Error),
    ("ios_base_failure", rpyfmm.FileError, rpyfmm.Error),
    ("invalid_argument", rpyfmm.InvalidArgumentError, ValueError),
    ("domain_error", rpyfmm.InvalidArgumentError, ValueError),
    ("out_of_range", rpyfmm.InvalidInputError, ValueError),
    ("overflow_error", rpyfmm.NumericalFailureError, ArithmeticError),
    ("runtime_error", rpyfmm.Error, RuntimeError),
    ("logic_error", rpyfmm.Error, RuntimeError),
    ("exception", rpyfmm.Error, RuntimeError),
]


@pytest.mark.parametrize("kind,cls,also", STD_EXCEPTIONS, ids=[k for k, _, _ in STD_EXCEPTIONS])
def test_std_exceptions_become_rpyfmm_errors(kind, cls, also):
    with pytest.raises(cls) as info:
        rpyfmm._rpyfmm._throw(kind)
    assert isinstance(info.value, rpyfmm.Error) and isinstance(info.value, also)
    assert type(info.value) is cls
    if kind != "bad_alloc":  # std::bad_alloc's what() is fixed by the library
        assert f"thrown {kind}" in str(info.value)


# ---------------------------------------------------------------------------------------------
# 5. Docstrings


def doc_text(obj) -> str:
    """The docstring without nanobind's signature lines ("name(...) -> ..." and "(self) -> ...")."""
    doc = getattr(obj, "__doc__", None) or ""
    name = getattr(obj, "__name__", None) or getattr(getattr(obj, "fget", None), "__name__", None)
    signatures = ("(self",) + ((name + "(",) if name else ())
    return "\n".join(line for line in doc.splitlines() if not line.startswith(signatures)).strip()


def test_every_public_name_has_a_docstring():
    missing = []
    for name in rpyfmm.__all__:
        obj = getattr(rpyfmm, name)
        if isinstance(obj, (int, float, str, tuple)):
            # Constants cannot carry a docstring: the package docstring describes each.
            if f"``{name}``" not in rpyfmm.__doc__:
                missing.append(name)
            continue
        if not doc_text(obj):
            missing.append(name)
        if isinstance(obj, type) and not issubclass(obj, BaseException):
            for member, value in vars(obj).items():
                if (member.startswith("_") and member != "__init__") or not callable(getattr(value, "fget", value)):
                    continue
                if not doc_text(value):
                    missing.append(f"{name}.{member}")
    assert not missing, f"without a docstring: {missing}"


def test_simd_level_reports_the_level_in_use():
    # The level is one of three names and follows RPYFMM_SIMD (read at the first query), so a
    # fresh interpreter with RPYFMM_SIMD=scalar reports scalar.
    assert rpyfmm.simd_level() in ("scalar", "avx2", "avx512")
    # Only the child's environment changes: this process's (and so the CLI runs of later tests)
    # keeps whatever RPYFMM_SIMD the suite was started with.
    out = run_isolated("print(rpyfmm.simd_level())", RPYFMM_SIMD="scalar")
    assert out.strip().splitlines()[-1] == "scalar"
