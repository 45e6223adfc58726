"""rpyfmm.mpi.Simulation: Brownian dynamics of a config stepped from Python across the ranks, each
rank holding its share, compared with the serial rpyfmm.Simulation on the whole system and with
rpyfmm.mpi.run_bd (docs/mpi.md, "Python (mpi4py)").

Run by ctest under mpirun on 1 and 2 ranks with distributed_operators.py (tests/mpi/CMakeLists.txt):
`mpirun -n 3 python -m pytest tests/python/mpi/distributed_bd.py`. Its name does not match
test_*.py, so that a plain pytest run of tests/python (one process, no mpirun) does not collect it.

The tests run in the same order on every rank and each one's collective calls all precede its
asserts, so that a failing assert on one rank cannot leave another waiting in a collective.
"""

from __future__ import annotations

import gc
import pathlib
import tempfile

import numpy as np
import pytest

MPI = pytest.importorskip("mpi4py.MPI", reason="rpyfmm.mpi needs mpi4py")

import rpyfmm  # noqa: E402
import rpyfmm.mpi  # noqa: E402

COMM = MPI.COMM_WORLD
RANK, SIZE = COMM.Get_rank(), COMM.Get_size()

# Configs of the serial and the whole-run tests: free-draining bead-spring chains in a periodic box
# (pair forces and bonds across the ranks' halos), 30 spheres with hydrodynamic interactions, and
# dipoles turning in a field (lattice, rotation).
from distributed_operators import CHAINS  # noqa: E402
from test_bd import CONFIG, ROTATING as ROTATING_DIRECT  # noqa: E402

# Rotation with free draining: orientations as well as positions bit for bit.
ROTATING = ROTATING_DIRECT.replace('method = "direct"', 'method = "none"')

# Hydrodynamic interactions by the exact operator with the sampler of the C++ test
# (tests/mpi/test_distributed_bd.cpp, DirectHydrodynamicsFollowTheSerialEngineToRoundOff): Lanczos
# without preconditioner at 1e-8.
LANCZOS = 'sqrt_method = "lanczos"\nsqrt_tolerance = 1e-8\nsqrt_preconditioner = "none"'
DIRECT = CONFIG.replace('method = "direct"', 'method = "direct"\n' + LANCZOS).replace("steps = 20", "steps = 12")


def gathered_positions(sim: rpyfmm.mpi.Simulation) -> np.ndarray | None:
    """The whole system's positions on rank 0 (None elsewhere)."""
    state = sim.gather()
    return None if state is None else state["positions"]


def serial_positions(config: str, steps: int) -> np.ndarray:
    sim = rpyfmm.Simulation.from_config(config)
    sim.run(steps)
    return np.array(sim.positions)


def every_rank_raises(call, match: str) -> list[str]:
    """Runs the collective `call`, expecting rpyfmm.Error matching `match`; every rank's message."""
    with pytest.raises(rpyfmm.Error, match=match) as caught:
        call()
    return COMM.allgather(f"{type(caught.value).__name__}: {caught.value}")


def test_free_draining_equals_serial_simulation_and_run_bd() -> None:
    # With free draining DistributedBd's positions are bd::Integrator's bit for bit on any number of
    # ranks (docs/mpi.md, "Brownian dynamics across ranks"), and rpyfmm.mpi.run_bd writes the same
    # run: its final frame is the gathered state to the XYZ file's 10 significant digits.
    root = pathlib.Path(COMM.bcast(tempfile.mkdtemp(prefix="rpyfmm-mpi-sim-") if RANK == 0 else None))
    summary = rpyfmm.mpi.run_bd(COMM, CHAINS, out_dir=str(root))
    sim = rpyfmm.mpi.Simulation(COMM, CHAINS)
    start = gathered_positions(sim)
    sim.run(40)
    x = gathered_positions(sim)
    assert summary["last_step"] == 40 and summary["engine"] == "mpi"
    assert sim.step_count == 40 and sim.global_size == 96
    assert sim.mobility == "none" and sim.dt == 0.002 and sim.time == pytest.approx(0.08)
    if RANK == 0:
        expected = serial_positions(CHAINS, 40)
        assert np.abs(expected - start).max() > 1e-3  # the run moved the beads
        np.testing.assert_array_equal(x, expected)
        _, steps, frames = rpyfmm.read_xyz(root / "trajectory.xyz")
        assert steps[-1] == 40
        # The file holds the positions wrapped into the box with 10 significant digits: within
        # 6e-9 of coordinates below 12 (a coordinate at the box face may be written as 0 or 12).
        d = np.abs(frames[-1] - np.mod(x, 12.0))
        np.testing.assert_array_less(np.minimum(d, np.abs(d - 12.0)), 1e-8)


def test_rotation_free_draining_equals_serial_simulation() -> None:
    # Free-draining rotation: orientations, like positions, are the serial engine's bit for bit.
    sim = rpyfmm.mpi.Simulation(COMM, ROTATING)
    sim.run(10)
    state = sim.gather()
    moments = sim.rotation_moments()
    local_q = sim.orientations
    assert local_q.shape == (sim.local_size, 4) and sim.velocities.shape == (0, 3)
    assert all(m == moments for m in COMM.allgather(moments))
    if RANK == 0:
        serial = rpyfmm.Simulation.from_config(ROTATING)
        serial.run(10)
        np.testing.assert_array_equal(state["positions"], serial.positions)
        np.testing.assert_array_equal(state["orientations"], serial.orientations)
        assert np.abs(serial.orientations[:, 0] - 1.0).max() > 1e-3  # the dipoles turned
        assert moments[0] > 0.0


def test_direct_hydrodynamics_follow_serial_to_round_off() -> None:
    # DistributedDirectRpy sums the same pairs as DirectRpy in another order, so products differ in
    # their last bits; Lanczos at 1e-8 carries that to ~1e-14 of a displacement, and 12 steps of
    # this force field keep it below the C++ test's bound of 1e-12 (coordinates of order 10).
    sim = rpyfmm.mpi.Simulation(COMM, DIRECT)
    assert sim.mobility == "direct"
    sim.run(12)
    x = gathered_positions(sim)
    energy = sim.potential_energy
    if RANK == 0:
        serial = rpyfmm.Simulation.from_config(DIRECT)
        start = np.array(serial.positions)
        serial.run(12)
        worst = np.abs(x - serial.positions).max()
        print(f"[mpi.Simulation direct] {SIZE} ranks: largest coordinate difference {worst:.3g}")
        assert worst < 1e-12
        assert np.abs(serial.positions - start).max() > 1e-2  # the particles moved far more
        # The energy is a sum over the ranks in another order: round-off of its terms.
        assert energy == pytest.approx(serial.last_report.potential_energy, rel=1e-12, abs=1e-12)


def test_step_then_run_equals_one_run() -> None:
    split = rpyfmm.mpi.Simulation(COMM, CHAINS)
    for _ in range(3):
        split.step()
    split.run(17)
    whole = rpyfmm.mpi.Simulation(COMM, CHAINS)
    whole.run(20)
    a, b = gathered_positions(split), gathered_positions(whole)
    assert split.step_count == whole.step_count == 20
    if RANK == 0:
        np.testing.assert_array_equal(a, b)


def test_shares_are_the_partition_of_the_gathered_state() -> None:
    # Every rank's (ids, positions, types) put together by global index is the gathered state: the
    # ids are a partition of 0 ... N - 1.
    sim = rpyfmm.mpi.Simulation(COMM, CHAINS)
    sim.run(10)
    state = sim.gather()
    shares = COMM.gather((sim.ids, sim.positions, sim.types, sim.last_forces), root=0)
    stats = COMM.allgather(sim.stats)
    energies = COMM.allgather(sim.potential_energy)
    assert sim.local_size == len(sim.ids) == len(sim.positions)
    assert all(s["rebuilds"] == stats[0]["rebuilds"] >= 1 and s["steps"] == 10 for s in stats)
    assert all(e == energies[0] for e in energies)
    if RANK == 0:
        ids = np.concatenate([s[0] for s in shares])
        assert ids.dtype == np.uint64 and np.array_equal(np.sort(ids), np.arange(96))
        for mine, x, t, f in shares:
            assert np.all(np.diff(mine.astype(np.int64)) > 0)  # increasing global index
            np.testing.assert_array_equal(x, state["positions"][mine])
            np.testing.assert_array_equal(t, state["types"][mine])
            assert f.shape == x.shape and np.all(np.isfinite(f))
        assert state["step"] == 10 and state["positions"].shape == (96, 3)


def test_arrays_keep_their_values_after_steps() -> None:
    # The arrays are copies that own their memory: a step (which may move particles between ranks
    # and reallocate the engine's arrays) and the simulation's end leave them as they were read.
    sim = rpyfmm.mpi.Simulation(COMM, CHAINS)
    sim.run(2)
    arrays = [sim.positions, sim.last_forces, sim.ids, sim.types]
    kept = [a.copy() for a in arrays]
    scratch = sim.positions
    scratch[...] = 0.0  # a writable copy: writing into it leaves the engine as it was
    np.testing.assert_array_equal(sim.positions, kept[0])
    sim.run(5)
    after = sim.positions
    del sim
    gc.collect()
    for a, k in zip(arrays, kept):
        np.testing.assert_array_equal(a, k)
    if len(after) == len(kept[0]) and len(after) > 0:
        assert np.abs(after - kept[0]).max() > 0.0  # the engine's positions did move


def test_bad_config_raises_on_every_rank() -> None:
    bad = CHAINS.replace("dt = 0.002", "dt = -1.0")
    messages = every_rank_raises(lambda: rpyfmm.mpi.Simulation(COMM, bad), "dt")
    assert all(m == messages[0] for m in messages)
    # Bad on one rank only: the others raise the same error instead of waiting for it.
    mine = bad if RANK == SIZE - 1 else CHAINS
    messages = every_rank_raises(lambda: rpyfmm.mpi.Simulation(COMM, mine), "dt")
    assert all(m == messages[0] for m in messages)
    missing = "/nonexistent/rpyfmm-config.toml" if RANK == 0 else CHAINS
    messages = every_rank_raises(lambda: rpyfmm.mpi.Simulation(COMM, missing), "rpyfmm-config.toml")
    assert all(m == messages[0] for m in messages)


def test_unsupported_config_and_calls_raise_on_every_rank() -> None:
    single = CHAINS.replace('method = "none"', 'method = "pse"\nwave_precision = "single"')
    messages = every_rank_raises(lambda: rpyfmm.mpi.Simulation(COMM, single), "single")
    assert all(m.startswith("NotSupportedError") and m == messages[0] for m in messages)
    sim = rpyfmm.mpi.Simulation(COMM, CHAINS)
    messages = every_rank_raises(lambda: sim.gather(root=SIZE), "root")
    assert all(m.startswith("InvalidArgumentError") and m == messages[0] for m in messages)
    messages = every_rank_raises(sim.rotation_moments, "rotation")
    assert all(m == messages[0] for m in messages)
    sim.step()  # the failures left the simulation usable
    assert sim.step_count == 1 and sim.kinetic_temperature() == 0.0
    with pytest.raises(rpyfmm.InvalidArgumentError, match="mpi4py"):
        rpyfmm.mpi.Simulation("not a communicator", CHAINS)
