"""rpyfmm.mpi.RigidBodyDynamics (docs/mpi.md, "Rigid-body Brownian dynamics across ranks" and
"Python (mpi4py)"): the bodies split over the ranks in uneven whole-body shares (rank 0 none where
there are several ranks), against the serial rpyfmm.RigidBodyDynamics with DirectRpy on the whole
set (also with a bead pair potential), and with DistributedPseRpy in a periodic box against the
serial engine with PseRpy; a restart by first_step; the bead operator's lifetime; bad input and a
failing force function on one rank.

Run by ctest under mpirun on 1, 2 and 3 ranks (tests/mpi/CMakeLists.txt):
`mpirun -n 2 python -m pytest tests/python/mpi/distributed_rigid_bd.py`. Its name does not match
test_*.py, so that a plain pytest run of tests/python does not collect it.

The tests run in the same order on every rank and each one's collective calls all precede its
asserts, so that a failing assert on one rank cannot leave another waiting in a collective.
"""

from __future__ import annotations

import gc

import numpy as np
import pytest

pytest.importorskip("mpi4py.MPI", reason="rpyfmm.mpi needs mpi4py")

import rpyfmm  # noqa: E402
import rpyfmm.mpi  # noqa: E402
from conftest import rel_err  # noqa: E402
from mpi_shares import COMM, RANK, SIZE  # noqa: E402
from mpi_shares import raised_on_every_rank as raised  # noqa: E402
from mpi_shares import share_without_first as body_share  # noqa: E402

VISCOSITY = 0.9
BODIES = 7  # 4 shells of 12 beads and 3 tetrahedra: 60 beads
STEPS = 3
# kT 1 with the RFD drift, GMRES to 1e-8 (the RFD solves to 1e-9) and the principal square root by
# Lanczos to 1e-6 without preconditioner, whose inner products are summed in the serial order
# across the ranks (docs/mpi.md, "Brownian displacements"): tests/mpi/test_distributed_rigid_bd.cpp's
# options.
OPTIONS = dict(dt=0.02, kT=1.0, seed=17, drift="rfd", rfd_delta=1e-3, tolerance=1e-8, sqrt_tolerance=1e-6,
               preconditioner="none")


def lattice(m: int, seed: int):
    """m bodies on a cubic lattice of spacing 3.2, as tests/mpi/test_distributed_rigid_bd.cpp builds
    them: icosphere shells of 12 touching beads (radius 1.2) and tetrahedra of 4 beads (bead radius
    0.5) alternately, each tracked at a point 0.3 off its centroid (so the drift does not vanish) and
    turned to a random orientation. Shape (N, 3), radii (N,), body offsets (m + 1), positions (m, 3),
    orientations (m, 4)."""
    rng = np.random.default_rng(seed)
    shell = 1.2 * rpyfmm.icosphere_beads(0)
    tetrahedron = 0.8 * np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=float)
    shape, radii, offsets = [], [], [0]
    for k in range(m):
        beads = shell if k % 2 == 0 else tetrahedron
        shape.append(beads - np.array([0.3, 0.0, 0.0]))
        radii.append(np.full(len(beads), 1.2 * rpyfmm.icosphere_bead_radius(0) if k % 2 == 0 else 0.5))
        offsets.append(offsets[-1] + len(beads))
    positions = 3.2 * np.array([[k % 3, k // 3 % 3, k // 9] for k in range(m)], dtype=float)
    q = rng.standard_normal((m, 4))
    return np.vstack(shape), np.concatenate(radii), np.array(offsets), positions, q / np.linalg.norm(
        q, axis=1, keepdims=True)


def trap(time, positions, orientations, bead_positions):
    """A harmonic trap about the origin on each reference point and a torque from the orientation:
    loads that depend on the state, so a wrong body's state in the function changes the trajectory."""
    assert len(bead_positions) >= len(positions)
    return np.hstack([-0.4 * positions, 0.5 * orientations[:, 1:]])


def local_bodies(bodies: slice, seed: int = 7):
    """This rank's shape, radii, body offsets (from 0), positions and orientations of the lattice."""
    shape, radii, offsets, positions, orientations = lattice(BODIES, seed)
    beads = slice(offsets[bodies.start], offsets[bodies.stop])
    return (shape[beads], radii[beads], list(offsets[bodies.start:bodies.stop + 1] - offsets[bodies.start]),
            positions[bodies], orientations[bodies])


def distributed(op, local, first_step: int = 0, forces=trap, **changes):
    shape, radii, offsets, positions, orientations = local
    options = dict(OPTIONS, **changes)
    return rpyfmm.mpi.RigidBodyDynamics(op, shape, radii, offsets, positions, orientations,
                                        first_step=first_step, forces=forces, **options)


def gathered(local: np.ndarray, columns: int) -> np.ndarray:
    """The ranks' rows concatenated in rank order, on every rank."""
    return np.concatenate(COMM.allgather(np.asarray(local).reshape(-1, columns)))


def iterations(report) -> tuple[int, int, int]:
    return report.solve_iterations, report.drift_iterations, report.sqrt_iterations


def test_matches_the_serial_engine() -> None:
    bodies = body_share(BODIES)
    op = rpyfmm.mpi.DistributedDirectRpy(COMM, viscosity=VISCOSITY)
    sim = distributed(op, local_bodies(bodies))
    steps = [iterations(sim.step()) for _ in range(STEPS)]
    q, quat, beads = gathered(sim.positions, 3), gathered(sim.orientations, 4), gathered(sim.bead_positions, 3)
    holders = COMM.allreduce(int(sim.local_bodies > 0))
    shape, radii, offsets, positions, orientations = lattice(BODIES, 7)
    serial = rpyfmm.RigidBodyDynamics(rpyfmm.DirectRpy(viscosity=VISCOSITY), shape, radii, list(offsets), positions,
                                      orientations, forces=trap, **OPTIONS)
    serial_steps = [iterations(serial.step()) for _ in range(STEPS)]
    # tests/mpi/test_distributed_rigid_bd.cpp: every product (DistributedDirectRpy) and every draw
    # (noise and RFD direction by global index, the principal root summed in the serial order) is
    # the serial engine's; only GMRES sums its inner products in another order, a few rounding
    # errors per solve, which the RFD divides by delta = 1e-3. The C++ test measured at most
    # 8.2e-16 (positions) and 9.6e-16 (orientations); its bound 1e-11 is that rounding times 1e3
    # with a margin of over ten, far below what a draw for the wrong body or bead changes (1.7e-4).
    # Where one rank holds every body the other ranks add exact zeros to every sum: bit for bit.
    # Measured (on main at 2189e9e with this binding, 2026-12-07, AMD EPYC, AVX-512, 2 cores shared
    # with other jobs): the serial iteration counts in every step, bit for bit on 1 and 2 ranks, at
    # most 4.9e-16 (positions) and 5.1e-16 (orientations) on 3 and 4 ranks.
    assert steps == serial_steps and all(s[1] > 0 and s[2] > 0 for s in steps)
    assert rel_err(q, serial.positions) <= 1e-11 and rel_err(quat, serial.orientations) <= 1e-11
    assert rel_err(beads, serial.bead_positions) <= 1e-11
    if holders == 1:
        assert np.array_equal(q, serial.positions) and np.array_equal(quat, serial.orientations)
        assert np.array_equal(beads, serial.bead_positions)
    assert not np.array_equal(q, lattice(BODIES, 7)[3])  # the bodies moved
    assert (sim.local_bodies, sim.first_body, sim.bodies) == (bodies.stop - bodies.start, bodies.start, BODIES)
    assert sim.local_beads == len(sim.bead_positions) and sim.lever_arms.shape == (sim.local_bodies,)
    assert np.array_equal(gathered(sim.lever_arms, 1).ravel(), serial.lever_arms)
    assert (sim.step_count, sim.time) == (STEPS, STEPS * OPTIONS["dt"])
    assert iterations(sim.last_report) == steps[-1]
    totals = sim.totals
    assert totals["steps"] == STEPS and totals["solve_iterations"] == sum(s[0] for s in steps)
    assert totals["drift_iterations"] == sum(s[1] for s in steps) and "solve" in totals["seconds"]


BOX = 10.0


def periodic_shells(seed: int):
    """4 icosphere shells of 12 beads (shell radius 1.5, every bead of radius 0.79: PSE takes one
    radius) tracked 0.3 off their centroids, at random orientations, on a 2 x 2 lattice of spacing 5
    in the box of side 10, as tests/mpi/test_distributed_rigid_bd.cpp builds them: the shells at
    x = 0.2 straddle the face x = 0, those at y = 9.9 the face y = L, and the last reference point
    (x = 15.2) lies outside the box. Shape, radii, body offsets, positions, orientations."""
    rng = np.random.default_rng(seed)
    frame = 1.5 * rpyfmm.icosphere_beads(0) - np.array([0.3, 0.0, 0.0])
    shape = np.vstack([frame] * 4)
    radii = np.full(len(shape), 1.5 * rpyfmm.icosphere_bead_radius(0))
    offsets = np.arange(5) * len(frame)
    positions = np.array([[0.2 + 5.0 * (k % 2) + (BOX if k == 3 else 0.0), 4.9 + 5.0 * (k // 2), 5.0]
                          for k in range(4)])
    q = rng.standard_normal((4, 4))
    return shape, radii, offsets, positions, q / np.linalg.norm(q, axis=1, keepdims=True)


def centre_trap(time, positions, orientations, bead_positions):
    """trap() about the box's centre (the reference points are never wrapped)."""
    return trap(time, positions - 0.5 * BOX, orientations, bead_positions)


def test_pse_in_a_periodic_box_matches_the_serial_engine() -> None:
    shape, radii, offsets, positions, orientations = periodic_shells(8)
    bodies = body_share(4)
    beads = slice(offsets[bodies.start], offsets[bodies.stop])
    op = rpyfmm.mpi.DistributedPseRpy(COMM, box=BOX, viscosity=VISCOSITY, tolerance=1e-6)
    sim = rpyfmm.mpi.RigidBodyDynamics(op, shape[beads], radii[beads],
                                       list(offsets[bodies.start:bodies.stop + 1] - offsets[bodies.start]),
                                       positions[bodies], orientations[bodies], forces=centre_trap, **OPTIONS)
    steps = [iterations(sim.step()) for _ in range(STEPS)]
    q, quat, bead_positions = gathered(sim.positions, 3), gathered(sim.orientations, 4), gathered(
        sim.bead_positions, 3)
    serial = rpyfmm.RigidBodyDynamics(
        rpyfmm.PseRpy(box=BOX, viscosity=VISCOSITY, tolerance=1e-6, wave_precision="double"), shape, radii,
        list(offsets), positions, orientations, forces=centre_trap, **OPTIONS)
    serial_steps = [iterations(serial.step()) for _ in range(STEPS)]
    # tests/mpi/test_distributed_rigid_bd.cpp: the bead products and the split sampler's B z agree
    # with PseRpy's (double grids) to 1e-12 (docs/mpi.md "Distributed PSE"), each solve to 1e-9
    # (the saddle-point system's amplification), and the RFD divides the difference of two solves
    # by delta = 1e-3: bound 1e-6, with the serial iteration counts in every step. Measured (AMD
    # EPYC, AVX-512, 2 cores shared with other jobs, 2026-12-07): the serial
    # iteration counts, at most 2.1e-16 (positions), 5.8e-16 (orientations) and 2.5e-16 (beads) on
    # 1-3 ranks; the trajectory without the drift differs by 2.6e-5, so the bound sees the RFD.
    assert steps == serial_steps and all(s[1] > 0 and s[2] > 0 for s in steps)
    assert rel_err(q, serial.positions) <= 1e-6 and rel_err(quat, serial.orientations) <= 1e-6
    assert rel_err(bead_positions, serial.bead_positions) <= 1e-6


def test_bead_pair_potential_matches_the_serial_engine() -> None:
    # pair= as rpyfmm.RigidBodyDynamics takes it: soft repulsion with sigma 0, the contact distance
    # of the first bead's radius in the global order (2 x 0.63 here, on rank 1 where rank 0 holds no
    # body), between the beads of different bodies on all ranks. Every rank sums its own beads' rows
    # of the serial bead forces in the serial order (tests/mpi/test_distributed_rigid_bd.cpp,
    # BeadForcesMatchTheSerialEngine), so the first step's energy is the serial one bit for bit and
    # the trajectory differs only as without pair: the bound 1e-11 of test_matches_the_serial_engine,
    # bit for bit where one rank holds every body. The potential moves the bodies (by more than 1e-5
    # relative against the run without it, far above that bound). Measured (2026-12-07, AMD EPYC,
    # AVX-512, 2 cores shared with other jobs): energies 0.18, 0.25, 0.22, bit for bit on 1 and 2
    # ranks, at most 2.9e-16 (positions) and 4.0e-16 (orientations) on 3 and 4 ranks; the
    # potential moves the bodies by 1.2e-4.
    pair = dict(kind="soft", epsilon=4.0)
    bodies = body_share(BODIES)
    op = rpyfmm.mpi.DistributedDirectRpy(COMM, viscosity=VISCOSITY)
    sim = distributed(op, local_bodies(bodies), pair=pair)
    energies = [sim.step().potential_energy for _ in range(STEPS)]
    q, quat = gathered(sim.positions, 3), gathered(sim.orientations, 4)
    holders = COMM.allreduce(int(sim.local_bodies > 0))
    shape, radii, offsets, positions, orientations = lattice(BODIES, 7)
    serial, without = (rpyfmm.RigidBodyDynamics(rpyfmm.DirectRpy(viscosity=VISCOSITY), shape, radii, list(offsets),
                                                positions, orientations, forces=trap, pair=p, **OPTIONS)
                       for p in (pair, None))
    serial_energies = [serial.step().potential_energy for _ in range(STEPS)]
    without.run(STEPS)
    assert energies[0] == serial_energies[0] and serial_energies[0] > 0.1
    assert rel_err(q, serial.positions) <= 1e-11 and rel_err(quat, serial.orientations) <= 1e-11
    if holders == 1:
        assert np.array_equal(q, serial.positions) and np.array_equal(quat, serial.orientations)
    assert rel_err(without.positions, serial.positions) >= 1e-5


def test_restart_continues_bit_for_bit() -> None:
    # The noise is keyed by (seed, step) and no other state carries over: the state after step 1,
    # restarted with first_step = 1 for two steps, is the three-step run's state bit for bit.
    bodies = body_share(BODIES)
    local = local_bodies(bodies)
    op = rpyfmm.mpi.DistributedDirectRpy(COMM, viscosity=VISCOSITY)
    whole = distributed(op, local)
    whole.run(STEPS)
    first = distributed(op, local)
    first.step()
    rest = distributed(op, local[:3] + (first.positions, first.orientations), first_step=1)
    report = rest.run(STEPS - 1)
    assert rest.step_count == STEPS and iterations(report) == iterations(whole.last_report)
    assert np.array_equal(rest.positions, whole.positions)
    assert np.array_equal(rest.orientations, whole.orientations)
    assert np.array_equal(rest.bead_positions, whole.bead_positions)


def test_operator_deleted_first_stays_alive() -> None:
    local = local_bodies(body_share(BODIES))
    op = rpyfmm.mpi.DistributedDirectRpy(COMM, viscosity=VISCOSITY)
    sim = distributed(op, local)
    reference = distributed(op, local)
    del op
    gc.collect()
    # The simulation keeps its bead operator alive: it still steps, the same bits as the other.
    sim.step()
    reference.step()
    assert np.array_equal(sim.positions, reference.positions)
    assert sim.comm is COMM


def test_bad_input_on_one_rank_raises_on_every_rank() -> None:
    local = local_bodies(body_share(BODIES))
    shape, radii, offsets, positions, orientations = local
    op = rpyfmm.mpi.DistributedDirectRpy(COMM, viscosity=VISCOSITY)
    last = RANK == SIZE - 1

    def on_last(bad, good):
        return bad if last else good

    nan_positions = positions.copy()
    if last:
        nan_positions[-1, 1] = np.nan
    messages = [
        raised(lambda: distributed(op, local[:3] + (nan_positions, orientations)), rpyfmm.InvalidInputError),
        raised(lambda: distributed(op, (shape, radii, on_last(None, offsets), positions, orientations))),
        raised(lambda: distributed(op, local[:4] + (on_last(orientations[:, :3], orientations),)),
               rpyfmm.InvalidInputError),
        raised(lambda: distributed(op, local, drift=on_last("bogus", "rfd")), rpyfmm.InvalidArgumentError),
        raised(lambda: distributed(op, local, forces=on_last(3, trap)), rpyfmm.InvalidArgumentError),
        raised(lambda: distributed(op, local, pair=on_last("bogus", "soft"))),
    ]
    # Options that differ between the ranks: every rank finds them (the message names the first).
    differ = [raised(lambda: distributed(op, local, dt=on_last(0.03, 0.02)), rpyfmm.InvalidArgumentError)
              ] if SIZE > 1 else []
    # A pair potential on one rank alone: every rank finds it.
    one_pair = raised(lambda: distributed(op, local, pair=on_last("soft", None)),
                      rpyfmm.InvalidArgumentError) if SIZE > 1 else []

    # A force function that raises, then one of the wrong shape, on the last rank after step 1:
    # every rank raises and keeps the state of step 1.
    def failing(time, q, quat, beads):
        if last and time > 0:
            raise ZeroDivisionError("trap broken")
        return trap(time, q, quat, beads)

    def wrong_shape(time, q, quat, beads):
        return trap(time, q, quat, beads)[:, :5] if last and time > 0 else trap(time, q, quat, beads)

    kept = []
    for forces, needle in ((failing, "ZeroDivisionError"), (wrong_shape, "expected (m, 6)")):
        sim = distributed(op, local, forces=forces)
        sim.step()
        q = sim.positions
        step_messages = raised(sim.step, rpyfmm.InvalidInputError)
        kept.append((needle, step_messages, sim.step_count, np.array_equal(sim.positions, q)))

    who = f"rank {SIZE - 1} of {SIZE}"
    for m in messages:
        assert len(set(m)) == 1 and who in m[0], m
    for m in differ:
        assert len(set(m)) == 1 and "different options" in m[0], m
    assert not one_pair or (len(set(one_pair)) == 1 and "pair must be given on every rank" in one_pair[0]), one_pair
    for needle, step_messages, count, same in kept:
        assert len(set(step_messages)) == 1 and needle in step_messages[0], step_messages
        assert count == 1 and same
