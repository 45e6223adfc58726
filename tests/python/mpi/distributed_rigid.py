"""rpyfmm.mpi.DistributedRigidBodies (docs/mpi.md, "Rigid bodies across ranks" and "Python
(mpi4py)"): the bodies split over the ranks in uneven whole-body shares (rank 0 none where there
are several ranks), against the serial rpyfmm.RigidBodies with DirectRpy on the whole set (apply,
apply_from, apply_with_noise, mobility_matrix) and with DistributedPseRpy in a periodic box against
rpyfmm.RigidBodies with PseRpy; the bead operator's lifetime; bad input on one rank.

Run by ctest under mpirun on 1, 2 and 3 ranks (tests/mpi/CMakeLists.txt):
`mpirun -n 2 python -m pytest tests/python/mpi/distributed_rigid.py`. Its name does not match
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
BODIES = 7  # 4 shells of 42 beads and 3 of 12: 204 beads


def rotation(q: np.ndarray) -> np.ndarray:
    """The rotation matrix of the quaternion q (w, x, y, z), normalized."""
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def shell_lattice(m: int, seed: int, mixed: bool = True):
    """m bead-shell spheres of radius 1.5 (icosphere shells of 42 and 12 touching beads
    alternately; all of 42 unless `mixed`) at random orientations on a cubic lattice of spacing 3.6
    (gaps of 0.6: strong coupling, several GMRES iterations), as tests/mpi/test_distributed_rigid.cpp
    builds them:
    positions (N, 3), radii (N,), body offsets (m + 1), forces and torques (m, 6)."""
    rng = np.random.default_rng(seed)
    x, radii, offsets = [], [], [0]
    for k in range(m):
        level = 1 if k % 2 == 0 or not mixed else 0
        shell = rpyfmm.icosphere_beads(level)
        centre = 3.6 * np.array([k % 3, k // 3 % 3, k // 9], dtype=float)
        x.append(centre + 1.5 * shell @ rotation(rng.standard_normal(4)).T)
        radii.append(np.full(len(shell), 1.5 * rpyfmm.icosphere_bead_radius(level)))
        offsets.append(offsets[-1] + len(shell))
    return np.vstack(x), np.concatenate(radii), np.array(offsets), rng.standard_normal((m, 6))


def local_system(x, radii, offsets, bodies: slice):
    """This rank's beads, radii and body offsets (from 0) for its bodies, and its beads' slice."""
    beads = slice(offsets[bodies.start], offsets[bodies.stop])
    return x[beads], radii[beads], offsets[bodies.start:bodies.stop + 1] - offsets[bodies.start], beads


def gathered(local: np.ndarray, columns: int) -> np.ndarray:
    """The ranks' rows concatenated in rank order, on every rank."""
    return np.concatenate(COMM.allgather(np.asarray(local).reshape(-1, columns)))


def serial_bodies(x, radii, offsets, **options):
    serial = rpyfmm.RigidBodies(rpyfmm.DirectRpy(viscosity=VISCOSITY), **options)
    serial.set_configuration(x, radii, list(offsets))
    return serial


@pytest.mark.parametrize("scalar_radius", [False, True])
def test_direct_matches_the_serial_solver(scalar_radius: bool) -> None:
    # With one radius for all beads (shells of 42 beads only), passed as a number.
    x, radii, offsets, ft = shell_lattice(BODIES, seed=3, mixed=not scalar_radius)
    bodies = body_share(len(offsets) - 1)
    lx, lr, lo, beads = local_system(x, radii, offsets, bodies)
    op = rpyfmm.mpi.DistributedDirectRpy(COMM, viscosity=VISCOSITY)
    rigid = rpyfmm.mpi.DistributedRigidBodies(op, tolerance=1e-10)
    rigid.set_configuration(lx, lr[0] if scalar_radius and len(lr) else lr, list(lo))
    u, f, report = rigid.apply_with_bead_forces(ft[bodies])
    u_only, report_only = rigid.apply(ft[bodies])
    serial = serial_bodies(x, radii, offsets, tolerance=1e-10)
    u_serial, f_serial, report_serial = serial.apply_with_bead_forces(ft)
    u_all, f_all = gathered(u, 6), gathered(f, 3)
    assert (rigid.local_bodies, rigid.local_beads) == (bodies.stop - bodies.start, beads.stop - beads.start)
    assert u.shape == (rigid.local_bodies, 6) and f.shape == (rigid.local_beads, 3)
    # The reference points default to each body's bead centroid (to round-off of the mean).
    centroids = np.array([lx[lo[k]:lo[k + 1]].mean(axis=0) for k in range(len(lo) - 1)]).reshape(-1, 3)
    assert rigid.reference_points.shape == centroids.shape
    assert np.allclose(rigid.reference_points, centroids, rtol=0, atol=1e-12)
    # rpyfmm/mpi/rigid_bodies.hpp: with DistributedDirectRpy (DirectRpy's products bit for bit) the
    # GMRES iterates differ from the serial solve only by the order of the inner products' sums;
    # tests/mpi/test_distributed_rigid.cpp measured relative differences of at most 3.2e-15 at
    # GMRES tolerance 1e-10; here 22 iterations and at most 5.1e-15 (bead forces, 4 ranks; 0 on 1
    # and 2 ranks, where one rank holds every body) at ebd7c63 on an AMD EPYC (AVX2, 2 cores shared
    # with other jobs). Bound 1e-12: a hundred times below the tolerance, so that two solves that
    # each merely met it would fail. On one rank the solve is the serial one bit for bit.
    assert report.iterations == report_serial.iterations and report.iterations > 3
    assert rel_err(u_all, u_serial) <= 1e-12 and rel_err(f_all, f_serial) <= 1e-12
    if SIZE == 1:
        assert np.array_equal(u_all, u_serial) and np.array_equal(f_all, f_serial)
        assert report.residual == report_serial.residual
    assert np.array_equal(u_only, u) and report_only.iterations == report.iterations


def test_noise_matches_the_serial_solver() -> None:
    x, radii, offsets, ft = shell_lattice(BODIES, seed=4)
    z = rpyfmm.normal_noise(len(x), 9)
    bodies = body_share(BODIES)
    lx, lr, lo, beads = local_system(x, radii, offsets, bodies)
    op = rpyfmm.mpi.DistributedDirectRpy(COMM, viscosity=VISCOSITY)
    rigid = rpyfmm.mpi.DistributedRigidBodies(op, tolerance=1e-10)
    rigid.set_configuration(lx, lr, list(lo))
    # The bead noise by global index: rpyfmm.mpi.normal_noise gives this rank's rows of z.
    z_local = rpyfmm.mpi.normal_noise(len(lx), op.offset, 9)
    u, report = rigid.apply_with_noise(ft[bodies], 0.8, z_local, sqrt_tolerance=1e-8, preconditioner="none")
    again, _ = rigid.apply_with_noise(ft[bodies], 0.8, z_local, sqrt_tolerance=1e-8, preconditioner="none")
    serial = serial_bodies(x, radii, offsets, tolerance=1e-10)
    u_serial, report_serial = serial.apply_with_noise(ft, 0.8, z, sqrt_tolerance=1e-8, preconditioner="none")
    # Without a preconditioner the distributed Lanczos sampler is the serial one bit for bit
    # (docs/mpi.md, "Brownian displacements"); the solves then differ as in
    # test_direct_matches_the_serial_solver: the same bound 1e-12 and the same iteration counts
    # (57 Lanczos and 24 GMRES iterations, at most 1.1e-15 on 1-4 ranks at ebd7c63, same machine).
    assert np.array_equal(z_local, z[beads])
    assert report.sqrt.iterations == report_serial.sqrt.iterations
    assert report.iterations == report_serial.iterations
    assert rel_err(gathered(u, 6), u_serial) <= 1e-12
    assert np.array_equal(again, u)


def test_apply_from_matches_the_serial_solver() -> None:
    x, radii, offsets, ft = shell_lattice(BODIES, seed=13)
    serial = serial_bodies(x, radii, offsets, tolerance=1e-10)
    # The guesses: the serial solution under forces and torques changed by 1 % (a nearby problem).
    nearby = ft + 0.01 * np.random.default_rng(17).standard_normal(ft.shape)
    u_guess, f_guess, from_zero = serial.apply_with_bead_forces(nearby)
    u_serial, f_serial, report_serial = serial.apply_from(ft, u_guess, f_guess)
    bodies = body_share(BODIES)
    lx, lr, lo, beads = local_system(x, radii, offsets, bodies)
    op = rpyfmm.mpi.DistributedDirectRpy(COMM, viscosity=VISCOSITY)
    rigid = rpyfmm.mpi.DistributedRigidBodies(op, tolerance=1e-10)
    rigid.set_configuration(lx, lr, list(lo))
    u, f, report = rigid.apply_from(ft[bodies], u_guess[bodies], f_guess[beads])
    flat_u, flat_f, _ = rigid.apply_from(ft[bodies].ravel(), u_guess[bodies].ravel(), f_guess[beads].ravel())
    _, report_zero = rigid.apply(ft[bodies])
    reports = COMM.allgather((report.iterations, report.restarts, report.residual))
    assert u.shape == (rigid.local_bodies, 6) and f.shape == (rigid.local_beads, 3)
    # The guess saves iterations, serially and across the ranks.
    assert report_serial.iterations < from_zero.iterations
    assert report.iterations < report_zero.iterations
    # As test_direct_matches_the_serial_solver, and tests/mpi/test_distributed_rigid.cpp
    # (ApplyFromMatchesTheSerialSolver): the iterates differ from the serial apply_from's with the
    # same guesses only by the order of the inner products' sums, so the same iteration count, and
    # bound 1e-12, a hundred times below the GMRES tolerance 1e-10 (two solves that each merely met
    # it would fail) and far above the few rounding errors of the sums' order; bit for bit on one
    # rank. Every rank takes the same GMRES steps: the same report everywhere.
    assert report.iterations == report_serial.iterations
    assert all(r == reports[0] for r in reports), reports
    assert rel_err(gathered(u, 6), u_serial) <= 1e-12 and rel_err(gathered(f, 3), f_serial) <= 1e-12
    if SIZE == 1:
        assert np.array_equal(u, u_serial) and np.array_equal(f, f_serial)
        assert report.residual == report_serial.residual
    # The flat layouts (6m,) and (3n,) are the same call.
    assert np.array_equal(flat_u, u) and np.array_equal(flat_f, f)


def test_mobility_matrix_matches_the_serial_matrix() -> None:
    x, radii, offsets, _ = shell_lattice(3, seed=6)
    bodies = body_share(3)
    lx, lr, lo, _ = local_system(x, radii, offsets, bodies)
    op = rpyfmm.mpi.DistributedDirectRpy(COMM, viscosity=VISCOSITY)
    rigid = rpyfmm.mpi.DistributedRigidBodies(op, tolerance=1e-10)
    rigid.set_configuration(lx, lr, list(lo))
    n = rigid.mobility_matrix()
    too_few = raised(lambda: rigid.mobility_matrix(max_bodies=2))
    n_serial = serial_bodies(x, radii, offsets, tolerance=1e-10).mobility_matrix()
    # Each column is one solve, which differs from the serial solve as in
    # test_direct_matches_the_serial_solver (bound 1e-12, a hundred times below the GMRES
    # tolerance); the matrix is symmetrized as the serial one, and the same on every rank.
    assert n.shape == (18, 18) and np.array_equal(n, n.T)
    assert rel_err(n, n_serial) <= 1e-12
    assert all(np.array_equal(n, other) for other in COMM.allgather(n))
    assert len(set(too_few)) == 1 and "max_bodies" in too_few[0]


def test_fmm_within_tolerance_of_the_serial_direct_solver() -> None:
    x, radii, offsets, ft = shell_lattice(BODIES, seed=5)
    bodies = body_share(BODIES)
    lx, lr, lo, _ = local_system(x, radii, offsets, bodies)
    op = rpyfmm.mpi.DistributedFmmRpy(COMM, viscosity=VISCOSITY, tolerance=1e-8, leaf_capacity=16)
    rigid = rpyfmm.mpi.DistributedRigidBodies(op, tolerance=1e-8)
    rigid.set_configuration(lx, lr, list(lo))
    u, _ = rigid.apply(ft[bodies])
    u_serial, _ = serial_bodies(x, radii, offsets, tolerance=1e-12).apply(ft)
    # The FMM's products within 1e-8 and GMRES to 1e-8: the velocities within 1e-7, a few times the
    # GMRES tolerance plus the FMM's (docs/theory/rigid.md; the C++ test's bound). Measured 1.9e-8
    # on 1-4 ranks at ebd7c63, same machine.
    assert rel_err(gathered(u, 6), u_serial) <= 1e-7


def periodic_shells(seed: int, box: float):
    """8 icosahedral shells of 12 touching beads (radius 1.5) at random orientations on a 2 x 2 x 2
    lattice of spacing box / 2, shifted so that some straddle the faces x = 0 and z = box, each bead
    wrapped into [0, box), as tests/mpi/test_distributed_rigid_periodic.cpp builds them:
    positions (N, 3), radii (N,), body offsets (9), forces and torques (8, 6)."""
    rng = np.random.default_rng(seed)
    shell = rpyfmm.icosphere_beads(0)
    x, offsets = [], [0]
    for k in range(8):
        centre = np.array([0.2, 2.5, 4.6]) + box / 2 * np.array([k % 2, k // 2 % 2, k // 4], dtype=float)
        x.append(np.mod(centre + 1.5 * shell @ rotation(rng.standard_normal(4)).T, box))
        offsets.append(offsets[-1] + len(shell))
    x = np.vstack(x)
    return x, np.full(len(x), 1.5 * rpyfmm.icosphere_bead_radius(0)), np.array(offsets), rng.standard_normal((8, 6))


def test_pse_in_a_periodic_box_matches_the_serial_solver() -> None:
    box = 10.0
    x, radii, offsets, ft = periodic_shells(3, box)
    bodies = body_share(8)
    lx, lr, lo, beads = local_system(x, radii, offsets, bodies)
    op = rpyfmm.mpi.DistributedPseRpy(COMM, box=box, viscosity=VISCOSITY, tolerance=1e-6)
    rigid = rpyfmm.mpi.DistributedRigidBodies(op, tolerance=1e-10)
    rigid.set_configuration(lx, lr, list(lo))
    u, f, report = rigid.apply_with_bead_forces(ft[bodies])
    z = np.random.default_rng(5).standard_normal(x.shape)
    u_noise, noise_report = rigid.apply_with_noise(ft[bodies], 0.7, z[beads])
    unequal = lr.copy()
    if RANK == SIZE - 1:
        unequal[-1] *= 1.1
    messages = raised(lambda: rigid.set_configuration(lx, unequal, list(lo)))
    serial = rpyfmm.RigidBodies(
        rpyfmm.PseRpy(box=box, viscosity=VISCOSITY, tolerance=1e-6, wave_precision="double"), tolerance=1e-10)
    serial.set_configuration(x, radii, list(offsets))
    u_serial, f_serial, r_serial = serial.apply_with_bead_forces(ft)
    u_noise_serial, noise_serial = serial.apply_with_noise(ft, 0.7, z)
    # DistributedPseRpy's products equal PseRpy's (double grids) to round-off (1e-12, docs/mpi.md
    # "Distributed PSE"); GMRES to 1e-10 amplifies that by the conditioning of the preconditioned
    # system: 1e-9, the C++ test's bound. Lever arms without minimum images (the straddling bodies'
    # beads lie at both ends of the box) change the velocities at O(1).
    assert report.iterations == r_serial.iterations
    assert rel_err(gathered(u, 6), u_serial) <= 1e-9
    assert rel_err(gathered(f, 3), f_serial) <= 1e-9
    assert noise_report.sqrt.iterations == noise_serial.sqrt.iterations
    assert rel_err(gathered(u_noise, 6), u_noise_serial) <= 1e-9
    assert "equal radii" in messages[0] and len(set(messages)) == 1


def test_operator_deleted_first_stays_alive() -> None:
    x, radii, offsets, ft = shell_lattice(3, seed=6)
    bodies = body_share(3)
    lx, lr, lo, _ = local_system(x, radii, offsets, bodies)
    op = rpyfmm.mpi.DistributedDirectRpy(COMM, viscosity=VISCOSITY)
    rigid = rpyfmm.mpi.DistributedRigidBodies(op)
    rigid.set_configuration(lx, lr, list(lo))
    u, _ = rigid.apply(ft[bodies])
    del op
    gc.collect()
    # The rigid-bodies object keeps its bead operator alive: it still solves, the same bits.
    again, _ = rigid.apply(ft[bodies])
    assert np.array_equal(again, u)
    assert rigid.comm is COMM


def test_bad_input_on_one_rank_raises_on_every_rank() -> None:
    x, radii, offsets, ft = shell_lattice(BODIES, seed=7)
    bodies = body_share(BODIES)
    lx, lr, lo, _ = local_system(x, radii, offsets, bodies)
    op = rpyfmm.mpi.DistributedDirectRpy(COMM, viscosity=VISCOSITY)
    rigid = rpyfmm.mpi.DistributedRigidBodies(op)
    last = RANK == SIZE - 1
    z = np.zeros_like(lx)

    messages = [
        raised(lambda: rigid.apply(ft[bodies])),  # before set_configuration
        raised(lambda: rigid.set_configuration(lx, lr, None if last else list(lo))),
        raised(lambda: rigid.set_configuration(lx[:, :2] if last else lx, lr, list(lo)),
               rpyfmm.InvalidInputError),
        raised(lambda: rigid.set_configuration(lx, lr, list(lo[:-1]) + [lo[-1] + 1] if last else list(lo))),
        raised(lambda: rigid.set_configuration(lx, lr, list(lo), np.zeros((len(lo) - 1, 2)) if last else None),
               rpyfmm.InvalidInputError),
    ]
    rigid.set_configuration(lx, lr, list(lo))
    bad_ft = ft[bodies].copy()
    guess_u, guess_f = np.full((rigid.local_bodies, 6), 0.1), np.full((rigid.local_beads, 3), 0.1)
    nan_guess_u = guess_u.copy()
    if last:
        bad_ft[0, 0] = np.nan
        nan_guess_u[-1, -1] = np.nan
    messages += [
        raised(lambda: rigid.apply(ft[bodies][:, :5] if last else ft[bodies]), rpyfmm.InvalidInputError),
        raised(lambda: rigid.apply(bad_ft)),
        raised(lambda: rigid.apply_with_noise(ft[bodies], 1.0, z[:, :2] if last else z),
               rpyfmm.InvalidInputError),
        raised(lambda: rigid.apply_with_noise(ft[bodies], -1.0 if last else 1.0, z)),
        raised(lambda: rigid.apply_from(ft[bodies], nan_guess_u, guess_f)),
        raised(lambda: rigid.apply_from(ft[bodies], guess_u, guess_f[:-1] if last else guess_f)),
        raised(lambda: rigid.apply_from(ft[bodies], guess_u[:, :5] if last else guess_u, guess_f),
               rpyfmm.InvalidInputError),
        raised(lambda: rigid.apply_from(ft[bodies], guess_u, guess_f[:, :2] if last else guess_f),
               rpyfmm.InvalidInputError),
    ]
    u, _ = rigid.apply(ft[bodies])  # and the solver works after each failure
    # GMRES options that differ between the ranks (the constructor's collective check).
    differ = []
    if SIZE > 1:
        differ.append(raised(lambda: rpyfmm.mpi.DistributedRigidBodies(op, tolerance=1e-7 if last else 1e-6)))
    for ranks in messages + differ:
        assert all(m == ranks[0] for m in ranks), ranks
    for ranks in messages[1:]:
        assert f"rank {SIZE - 1} of {SIZE}" in ranks[0], ranks[0]
    # The guesses' checks name them (the NaN velocity and the bead forces one bead short).
    assert "guess velocities" in messages[-4][0] and "guess bead forces" in messages[-3][0], messages[-4:]
    assert "guess_velocities" in messages[-2][0] and "guess_bead_forces" in messages[-1][0], messages[-2:]
    assert np.all(np.isfinite(u))
