"""rpyfmm.mpi across ranks: each rank holds a share of one random suspension, and the ranks'
results gathered in rank order are compared with the serial operators on the whole system.

Run by ctest under mpirun on 1 and 2 ranks (tests/mpi/CMakeLists.txt, label mpi), every rank
running pytest on this file: `mpirun -n 2 python -m pytest tests/python/mpi/distributed_operators.py`.
Its name does not match test_*.py, so that a plain pytest run of tests/python (one process,
no mpirun) does not collect it.

The tests run in the same order on every rank and each one's collective calls all precede its
asserts, so that a failing assert on one rank cannot leave another waiting in a collective.
"""

from __future__ import annotations

import gc

import numpy as np
import pytest

MPI = pytest.importorskip("mpi4py.MPI", reason="rpyfmm.mpi needs mpi4py")

import rpyfmm  # noqa: E402
import rpyfmm.mpi  # noqa: E402
from conftest import rel_err, suspension  # noqa: E402

COMM = MPI.COMM_WORLD
RANK, SIZE = COMM.Get_rank(), COMM.Get_size()


def share(n: int, empty_first: bool = False) -> slice:
    """This rank's slice of n particles: uneven shares (rank r gets about r + 1 parts), or with
    rank 0 holding none when `empty_first` (and more than one rank)."""
    weights = np.arange(1, SIZE + 1, dtype=float)
    if empty_first and SIZE > 1:
        weights[0] = 0.0
    bounds = np.rint(np.concatenate([[0.0], np.cumsum(weights)]) / weights.sum() * n).astype(int)
    return slice(bounds[RANK], bounds[RANK + 1])


def gathered(local: np.ndarray) -> np.ndarray:
    """The ranks' (n, 3) arrays concatenated in rank order, on every rank."""
    return np.concatenate(COMM.allgather(np.asarray(local).reshape(-1, 3)))


def system(n: int, seed: int, radii: bool):
    """Positions (n, 3), one radius or n radii in [0.8, 1.2], and forces, the same on every rank."""
    x = suspension(n, seed=seed)
    rng = np.random.default_rng(seed + 1)
    a = rng.uniform(0.8, 1.2, n) if radii else 1.0
    return x, a, rng.standard_normal((n, 3))


def local_radius(a, part: slice):
    return a[part] if isinstance(a, np.ndarray) else a


@pytest.mark.parametrize("radii", [False, True])
@pytest.mark.parametrize("empty_first", [False, True])
def test_direct_equals_serial(radii: bool, empty_first: bool) -> None:
    x, a, f = system(300, seed=11, radii=radii)
    part = share(len(x), empty_first)
    op = rpyfmm.mpi.DistributedDirectRpy(COMM, viscosity=0.7)
    op.set_positions(x[part], local_radius(a, part))
    u = gathered(op.apply(f[part]))
    serial = rpyfmm.DirectRpy(viscosity=0.7)
    serial.set_positions(x, a)
    # docs/mpi.md: the distributed product equals DirectRpy's on the concatenated shares bit for bit.
    assert np.array_equal(u, serial.apply(f))
    assert (op.local_size, op.global_size, op.offset) == (part.stop - part.start, len(x), part.start)


@pytest.mark.parametrize("radii", [False, True])
@pytest.mark.parametrize("empty_first", [False, True])
def test_direct_rotation_against_serial(radii: bool, empty_first: bool) -> None:
    # 600 particles: DirectRpy's source blocks of 256 straddle the ranks' shares.
    x, a, f = system(600, seed=12, radii=radii)
    t = np.random.default_rng(13).uniform(-1.0, 1.0, (len(x), 3))
    part = share(len(x), empty_first)
    op = rpyfmm.mpi.DistributedDirectRpy(COMM, viscosity=0.7)
    op.set_positions(x[part], local_radius(a, part))
    u_local, w_local = op.apply(f[part], t[part])
    u, w = gathered(u_local), gathered(w_local)
    serial = rpyfmm.DirectRpy(viscosity=0.7)
    serial.set_positions(x, a)
    u_serial, w_serial = serial.apply(f, t)
    assert op.supports_rotation
    assert u_local.shape == f[part].shape and w_local.shape == f[part].shape
    # docs/mpi.md: the translational and rotational sums both go over DirectRpy's source blocks,
    # so U and W equal DirectRpy's on the concatenated shares bit for bit.
    assert np.array_equal(u, u_serial) and np.array_equal(w, w_serial)


def test_direct_rotation_bad_input_raises_on_every_rank() -> None:
    x, a, f = system(60, seed=34, radii=False)
    t = np.ones_like(f)
    part = share(len(x))
    op = rpyfmm.mpi.DistributedDirectRpy(COMM)
    op.set_positions(x[part], a)
    last = RANK == SIZE - 1
    messages = []
    # Torques of another shape than the forces, a NaN torque, `out` with torques: on one rank.
    for torques, out, error in [
        (t[part][:, :2] if last else t[part], None, rpyfmm.InvalidInputError),
        (np.where(last, np.nan, t[part]), None, rpyfmm.InvalidInputError),
        (t[part], np.empty_like(f[part]) if RANK == 0 else None, rpyfmm.InvalidArgumentError),
    ]:
        with pytest.raises(error) as caught:
            op.apply(f[part], torques, out=out)
        messages.append(COMM.allgather(str(caught.value)))
    u, w = op.apply(f[part], t[part])  # and the operator works after each failure
    for ranks in messages:
        assert all(m == ranks[0] for m in ranks)
    shape, nan, out = (ranks[0] for ranks in messages)
    assert f"rank {SIZE - 1} of {SIZE}" in shape and "torques has shape" in shape
    assert f"rank {SIZE - 1} of {SIZE}" in nan and "local torques entry (0, 0) is NaN" in nan
    assert "rank 0 of" in out and "out is not supported together with torques" in out
    assert np.all(np.isfinite(u)) and np.all(np.isfinite(w))


@pytest.mark.parametrize(
    "method, preconditioner", [("lanczos", "none"), ("chebyshev", "none"), ("lanczos", "block")]
)
def test_direct_sqrt_equals_serial(method: str, preconditioner: str) -> None:
    x, a, _ = system(200, seed=12, radii=True)
    z = rpyfmm.normal_noise(len(x), 5)
    # docs/mpi.md, "Brownian displacements": every inner product is summed in the serial order and
    # the block preconditioner's blocks are the serial ones of the whole set, whatever the partition.
    part = share(len(x))
    keywords = dict(method=method, preconditioner=preconditioner, tolerance=1e-6)
    op = rpyfmm.mpi.DistributedDirectRpy(COMM)
    op.set_positions(x[part], a[part])
    w, report = op.apply_sqrt(z[part], **keywords)
    w = gathered(w)
    serial = rpyfmm.DirectRpy()
    serial.set_positions(x, a)
    w_serial, report_serial = serial.apply_sqrt(z, **keywords)
    assert np.array_equal(w, w_serial)
    assert report.iterations == report_serial.iterations


@pytest.mark.parametrize("kind", ["direct", "pse"])
def test_unsupported_sampler_raises_on_every_rank(kind: str) -> None:
    x = np.random.default_rng(16).uniform(0.0, 12.0, (40, 3))
    part = share(len(x))
    if kind == "direct":
        op, method = rpyfmm.mpi.DistributedDirectRpy(COMM), "cholesky"
    else:
        op, method = rpyfmm.mpi.DistributedPseRpy(COMM, box=12.0), "lanczos"
    op.set_positions(x[part], 1.0)
    with pytest.raises(rpyfmm.NotSupportedError) as caught:
        op.apply_sqrt(np.ones_like(x[part]), method=method)
    messages = COMM.allgather(str(caught.value))
    assert all(m == messages[0] for m in messages)


@pytest.mark.parametrize("overlap_exchange", [False, True])
@pytest.mark.parametrize("tolerance", [1e-3, 1e-6])
def test_fmm_within_tolerance(tolerance: float, overlap_exchange: bool) -> None:
    x, a, f = system(3000, seed=13, radii=True)
    part = share(len(x))
    op = rpyfmm.mpi.DistributedFmmRpy(COMM, tolerance=tolerance, overlap_exchange=overlap_exchange)
    op.set_positions(x[part], a[part])
    u = gathered(op.apply(f[part]))
    exact = rpyfmm.DirectRpy()
    exact.set_positions(x, a)
    serial = rpyfmm.FmmRpy(tolerance=tolerance)
    serial.set_positions(x, a)
    u_exact = exact.apply(f)
    # The contract (docs/mpi.md, "Distributed FmmRpy"): relative l2 error against the exact product
    # at most the tolerance; the serial FmmRpy meets the same, so the two differ by at most twice it.
    assert rel_err(u, u_exact) <= tolerance
    assert rel_err(u, serial.apply(f)) <= 2 * tolerance
    assert op.tolerance == tolerance


@pytest.mark.parametrize("tolerance", [1e-3, 1e-6])
def test_fmm_rotation_within_tolerance(tolerance: float) -> None:
    x, a, f = system(1500, seed=14, radii=True)
    t = np.random.default_rng(15).uniform(-1.0, 1.0, (len(x), 3))
    part = share(len(x), empty_first=True)
    op = rpyfmm.mpi.DistributedFmmRpy(COMM, viscosity=0.7, tolerance=tolerance)
    op.set_positions(x[part], a[part])
    u_local, w_local = op.apply(f[part], t[part])
    exact = rpyfmm.DirectRpy(viscosity=0.7)
    exact.set_positions(x, a)
    u_exact, w_exact = exact.apply(f, t)
    # The contract with torques (docs/mpi.md, "Distributed FmmRpy"): the relative l2 error of U and
    # of W, each over all particles, at most the tolerance against the exact grand product.
    assert op.supports_rotation
    assert u_local.shape == f[part].shape and w_local.shape == f[part].shape
    assert rel_err(gathered(u_local), u_exact) <= tolerance
    assert rel_err(gathered(w_local), w_exact) <= tolerance
    # Without torques the product is the force-only one.
    assert np.array_equal(op.apply(f[part], np.zeros_like(t[part]))[0], op.apply(f[part]))


@pytest.mark.parametrize("kind", ["direct", "fmm"])
@pytest.mark.parametrize("flat", [False, True])
def test_apply_block_columns_are_single_products(kind: str, flat: bool) -> None:
    x, a, f = system(400, seed=17, radii=True)
    # Three right-hand sides with loads near 1e300, 1 and 1e-300: each is scaled by its own power
    # of two, so none underflows or overflows beside the others.
    block = np.stack([1e300 * f, f[::-1].copy(), 1e-300 * np.roll(f, 1, axis=0)])
    part = share(len(x), empty_first=True)
    op = {
        "direct": lambda: rpyfmm.mpi.DistributedDirectRpy(COMM, viscosity=0.7),
        "fmm": lambda: rpyfmm.mpi.DistributedFmmRpy(COMM, viscosity=0.7, tolerance=1e-6),
    }[kind]()
    op.set_positions(x[part], a[part])
    local = block[:, part, :]
    if flat:
        local = local.reshape(3, -1)
    u = op.apply_block(local)
    singles = [op.apply(local[r]) for r in range(3)]
    out = np.empty_like(local)
    same_out = op.apply_block(local, out=out)
    with pytest.raises(rpyfmm.InvalidInputError) as caught:
        op.apply_block(local[:, :-1] if RANK == SIZE - 1 else local)
    messages = COMM.allgather(str(caught.value))
    # docs/mpi.md: each right-hand side of apply_block equals apply of it alone, bit for bit.
    assert u.shape == local.shape
    assert all(np.array_equal(u[r], singles[r]) for r in range(3))
    assert same_out is out and np.array_equal(out, u)
    assert all(m == messages[0] for m in messages) and f"rank {SIZE - 1} of {SIZE}" in messages[0]
    if kind == "direct":
        serial = rpyfmm.DirectRpy(viscosity=0.7)
        serial.set_positions(x, a)
        whole = np.concatenate(COMM.allgather(u.reshape(3, -1, 3)), axis=1)
        assert np.array_equal(whole, serial.apply_block(block))


@pytest.mark.parametrize("kind", ["direct", "fmm", "pse"])
def test_apply_sqrt_rotation_equals_serial(kind: str) -> None:
    x, a, _ = system(240, seed=18, radii=kind != "pse")
    rng = np.random.default_rng(19)
    z_t, z_r = rng.standard_normal((len(x), 3)), rng.standard_normal((len(x), 3))
    part = share(len(x), empty_first=True)
    op, serial = {
        "direct": lambda: (rpyfmm.mpi.DistributedDirectRpy(COMM, viscosity=0.7), rpyfmm.DirectRpy(viscosity=0.7)),
        "fmm": lambda: (rpyfmm.mpi.DistributedFmmRpy(COMM, viscosity=0.7, tolerance=1e-9),
                        rpyfmm.DirectRpy(viscosity=0.7)),
        "pse": lambda: (rpyfmm.mpi.DistributedPseRpy(COMM, box=20.0, viscosity=0.7, tolerance=1e-6),
                        rpyfmm.PseRpy(box=20.0, viscosity=0.7, tolerance=1e-6, wave_precision="double")),
    }[kind]()
    op.set_positions(x[part], local_radius(a, part))
    w_t, w_r, report = op.apply_sqrt_rotation(z_t[part], z_r[part], tolerance=1e-6)
    with pytest.raises(rpyfmm.InvalidInputError) as caught:
        op.apply_sqrt_rotation(z_t[part], z_r[part][:, :2] if RANK == SIZE - 1 else z_r[part])
    messages = COMM.allgather(str(caught.value))
    serial.set_positions(x, a)
    s_t, s_r, s_report = serial.apply_sqrt_rotation(z_t, z_r, tolerance=1e-6)
    w_t, w_r = gathered(w_t), gathered(w_r)
    # docs/mpi.md: with the direct operator the sampler is the serial one bit for bit; the PSE's is
    # PseRpy's with double grids to round-off (1e-12); the FMM at 1e-9 is the direct operator to
    # 1e-9, far below the sampler's 1e-6, and each stops within its tolerance of its own root: 1e-5.
    if kind == "direct":
        assert np.array_equal(w_t, s_t) and np.array_equal(w_r, s_r)
        assert report.iterations == s_report.iterations
    else:
        bound = 1e-12 if kind == "pse" else 1e-5
        assert rel_err(w_t, s_t) <= bound and rel_err(w_r, s_r) <= bound
    assert all(m == messages[0] for m in messages) and f"rank {SIZE - 1} of {SIZE}" in messages[0]
    assert "z_rotation has shape" in messages[0]


def test_fmm_sqrt_covariance_product() -> None:
    # w = M_fmm^{1/2} z on the ranks: M_fmm^{-1/2} cannot be checked directly, but w . w = z . M_fmm z
    # up to the sampler's tolerance, with M_fmm z from apply.
    x, a, _ = system(800, seed=14, radii=False)
    z = rpyfmm.normal_noise(len(x), 9)
    part = share(len(x))
    op = rpyfmm.mpi.DistributedFmmRpy(COMM, tolerance=1e-8)
    op.set_positions(x[part], a)
    w, report = op.apply_sqrt(z[part], tolerance=1e-8)
    mz = gathered(op.apply(z[part]))
    w = gathered(w)
    assert report.iterations > 0
    assert abs(np.vdot(w, w) - np.vdot(z, mz)) <= 1e-6 * np.vdot(z, mz)


def pse_pair(n: int, box: float, tolerance: float):
    x = np.random.default_rng(21).uniform(0.0, box, (n, 3))
    op = rpyfmm.mpi.DistributedPseRpy(COMM, box=box, viscosity=0.9, tolerance=tolerance)
    serial = rpyfmm.PseRpy(box=box, viscosity=0.9, tolerance=tolerance, wave_precision="double")
    serial.set_positions(x, 1.0)
    return x, op, serial


def test_pse_equals_serial() -> None:
    x, op, serial = pse_pair(250, box=14.0, tolerance=1e-4)
    f = np.random.default_rng(22).standard_normal(x.shape)
    part = share(len(x))
    op.set_positions(x[part], 1.0)
    u = gathered(op.apply(f[part]))
    w, _ = op.sample(seed=3, step=2)
    w = gathered(w)
    un = gathered(op.apply_with_noise(f[part], 0.5, seed=3, step=2)[0])
    params = op.parameters
    u_serial = serial.apply(f)
    w_serial, _ = serial.sample(seed=3, step=2)
    un_serial, _ = serial.apply_with_noise(f, 0.5, seed=3, step=2)
    # docs/mpi.md, "Distributed PSE": PseRpy's sums on the whole set, added in another order.
    assert np.max(np.abs(u - u_serial)) <= 1e-12 * np.max(np.abs(u_serial))
    assert np.max(np.abs(w - w_serial)) <= 1e-12 * np.max(np.abs(w_serial))
    assert np.max(np.abs(un - un_serial)) <= 1e-12 * np.max(np.abs(un_serial))
    assert params["grid"] == serial.parameters["grid"]


def test_pse_rotation_equals_serial() -> None:
    x, op, serial = pse_pair(250, box=14.0, tolerance=1e-4)
    rng = np.random.default_rng(23)
    f, t = rng.standard_normal(x.shape), rng.standard_normal(x.shape)
    part = share(len(x), empty_first=True)
    op.set_positions(x[part], 1.0)
    u_local, w_local = op.apply(f[part], t[part])
    u, w = gathered(u_local), gathered(w_local)
    u_serial, w_serial = serial.apply(f, t)
    assert op.supports_rotation
    assert u_local.shape == f[part].shape and w_local.shape == f[part].shape
    # docs/mpi.md, "Distributed PSE", Rotation: PseRpy's grand product, its sums added in another order.
    assert np.max(np.abs(u - u_serial)) <= 1e-12 * np.max(np.abs(u_serial))
    assert np.max(np.abs(w - w_serial)) <= 1e-12 * np.max(np.abs(w_serial))


def test_pse_apply_sqrt_equals_serial() -> None:
    x, op, serial = pse_pair(200, box=12.0, tolerance=1e-4)
    z = rpyfmm.normal_noise(len(x), 4)
    part = share(len(x), empty_first=True)
    op.set_positions(x[part], 1.0)
    w, _ = op.apply_sqrt(z[part])
    w = gathered(w)
    w_serial, _ = serial.apply_sqrt(z)
    assert np.max(np.abs(w - w_serial)) <= 1e-12 * np.max(np.abs(w_serial))


@pytest.mark.parametrize("overlap_exchange", [False, True])
@pytest.mark.parametrize("with_targets", [False, True])
def test_laplace_within_tolerance(with_targets: bool, overlap_exchange: bool) -> None:
    rng = np.random.default_rng(17)
    x, q, y = rng.uniform(0.0, 1.0, (4000, 3)), rng.standard_normal((2, 4000)), rng.uniform(0.0, 1.0, (500, 3))
    part, tpart = share(len(x)), share(len(y), empty_first=True)
    fmm = rpyfmm.mpi.DistributedLaplaceFmm(COMM, tolerance=1e-6, overlap_exchange=overlap_exchange)
    # With targets, rank 0 passes None (no targets of its own) when there are several ranks.
    local_targets = y[tpart] if with_targets and tpart.stop > tpart.start else None
    fmm.set_points(x[part], local_targets)
    r = fmm.evaluate(q[:, part], outputs="all")
    r = np.concatenate(COMM.allgather(r), axis=1)
    exact = rpyfmm.laplace_direct(x, q, y if with_targets else None)
    assert r.shape == exact.shape
    # The contract (docs/mpi.md, "Distributed Laplace FMM"): relative l2 error of each output.
    for d in range(2):
        for cols in (slice(0, 1), slice(1, 4), slice(4, 10)):
            assert rel_err(r[d][:, cols], exact[d][:, cols]) <= 1e-6
    assert fmm.global_size == len(x) and fmm.local_size == part.stop - part.start


def test_hilbert_curve_meets_the_same_contracts() -> None:
    rng = np.random.default_rng(23)
    x, q = rng.uniform(0.0, 1.0, (3000, 3)), rng.standard_normal((1, 3000))
    part = share(len(x))
    fmm = rpyfmm.mpi.DistributedLaplaceFmm(COMM, tolerance=1e-6, curve="hilbert")
    fmm.set_points(x[part])
    r = np.concatenate(COMM.allgather(fmm.evaluate(q[:, part], outputs="all")), axis=1)
    y, a, f = system(1500, seed=29, radii=True)
    op = rpyfmm.mpi.DistributedFmmRpy(COMM, tolerance=1e-6, curve="hilbert")
    ypart = share(len(y))
    op.set_positions(y[ypart], a[ypart])
    u = gathered(op.apply(f[ypart]))
    exact = rpyfmm.DirectRpy()
    exact.set_positions(y, a)
    # The contracts of docs/mpi.md ("Distributed Laplace FMM", "Distributed FmmRpy") hold for either
    # curve: the relative l2 error of each output, and of U, at most the tolerance.
    expected = rpyfmm.laplace_direct(x, q)
    for cols in (slice(0, 1), slice(1, 4), slice(4, 10)):
        assert rel_err(r[0][:, cols], expected[0][:, cols]) <= 1e-6
    assert rel_err(u, exact.apply(f)) <= 1e-6
    assert fmm.curve == "hilbert" and op.curve == "hilbert"
    assert rpyfmm.mpi.DistributedFmmRpy(COMM).curve == "morton"


def test_unknown_curve_raises_on_every_rank() -> None:
    name = "peano" if RANK == SIZE - 1 else "morton"
    with pytest.raises(rpyfmm.InvalidArgumentError, match="'morton' or 'hilbert'") as laplace:
        rpyfmm.mpi.DistributedLaplaceFmm(COMM, curve=name)
    with pytest.raises(rpyfmm.InvalidArgumentError, match="'morton' or 'hilbert'") as fmm:
        rpyfmm.mpi.DistributedFmmRpy(COMM, curve=name)
    for caught in (laplace, fmm):
        messages = COMM.allgather(str(caught.value))
        assert all(m == messages[0] for m in messages), messages


def test_normal_noise_is_the_serial_rows() -> None:
    part = share(90, empty_first=True)
    z = rpyfmm.mpi.normal_noise(part.stop - part.start, part.start, seed=7, step=3, stream=1)
    assert np.array_equal(gathered(z), rpyfmm.normal_noise(90, 7, 3, stream=1))


@pytest.mark.parametrize("kind", ["direct", "fmm", "pse"])
def test_nan_on_one_rank_raises_on_every_rank(kind: str) -> None:
    x, a, f = system(100, seed=31, radii=False)
    part = share(len(x))
    op = {
        "direct": lambda: rpyfmm.mpi.DistributedDirectRpy(COMM),
        "fmm": lambda: rpyfmm.mpi.DistributedFmmRpy(COMM, tolerance=1e-4),
        "pse": lambda: rpyfmm.mpi.DistributedPseRpy(COMM, box=20.0, tolerance=1e-3),
    }[kind]()
    bad = x[part].copy()
    if RANK == SIZE - 1:
        bad[0, 1] = np.nan
    with pytest.raises(rpyfmm.InvalidInputError) as caught:
        op.set_positions(bad, a)
    messages = COMM.allgather(str(caught.value))
    # The operator works again after the collective failure.
    op.set_positions(x[part], a)
    u = gathered(op.apply(f[part]))
    assert all(m == messages[0] for m in messages)
    assert f"rank {SIZE - 1} of {SIZE}" in messages[0] and "NaN" in messages[0]
    assert u.shape == x.shape and np.all(np.isfinite(u))


def test_bad_shape_on_one_rank_raises_on_every_rank() -> None:
    x, a, f = system(60, seed=32, radii=False)
    part = share(len(x))
    op = rpyfmm.mpi.DistributedDirectRpy(COMM)
    op.set_positions(x[part], a)
    forces = f[part] if RANK != SIZE - 1 else f[part][:, :2]  # (n, 2) on the last rank only
    with pytest.raises(rpyfmm.InvalidInputError) as caught:
        op.apply(forces)
    messages = COMM.allgather(str(caught.value))
    assert all(m == messages[0] for m in messages)
    assert f"rank {SIZE - 1} of {SIZE}" in messages[0] and "forces has shape" in messages[0]


def test_operator_keeps_its_communicator() -> None:
    x, a, f = system(50, seed=33, radii=False)
    part = share(len(x))
    dup = COMM.Dup()
    op = rpyfmm.mpi.DistributedDirectRpy(dup)
    del dup
    gc.collect()
    op.set_positions(x[part], a)
    u = gathered(op.apply(f[part]))
    comm = op.comm
    serial = rpyfmm.DirectRpy()
    serial.set_positions(x, a)
    assert isinstance(comm, MPI.Intracomm) and comm != MPI.COMM_NULL
    assert np.array_equal(u, serial.apply(f))


def test_not_a_communicator() -> None:
    with pytest.raises(rpyfmm.InvalidArgumentError, match="mpi4py communicator"):
        rpyfmm.mpi.DistributedDirectRpy(42)


CHAINS = """
[system]
geometry = "periodic"
box = [12.0, 12.0, 12.0]
[[types]]
name = "A"
radius = 0.5
[particles]
source = "chains"
chains = 12
beads = 8
[[pair]]
types = ["A", "A"]
kind = "wca"
[bonds]
kind = "harmonic"
k = 100.0
length = 1.0
[integrator]
dt = 0.002
steps = 40
seed = 5
[mobility]
method = "none"
[output]
trajectory_every = 10
log_every = 10
checkpoint_every = 20
"""


def test_run_bd_across_ranks_writes_the_serial_trajectory() -> None:
    # Free-draining bead-spring chains: the trajectory of a run across the ranks, and of 20 steps
    # across the ranks continued by restart_bd, is the serial run's byte for byte.
    import pathlib
    import tempfile

    root = pathlib.Path(COMM.bcast(tempfile.mkdtemp(prefix="rpyfmm-mpi-bd-") if RANK == 0 else None))
    serial_ran = True
    if RANK == 0:  # a failure here reaches every rank before any collective run
        try:
            rpyfmm.run_bd(CHAINS, out_dir=str(root / "serial"))
        except Exception as e:  # noqa: BLE001
            serial_ran = repr(e)
    serial_ran = COMM.bcast(serial_ran)
    assert serial_ran is True, serial_ran
    whole = rpyfmm.mpi.run_bd(COMM, CHAINS, out_dir=str(root / "ranks"))
    rpyfmm.mpi.run_bd(COMM, CHAINS, steps=20, out_dir=str(root / "half"))
    resumed = rpyfmm.mpi.restart_bd(COMM, str(root / "half" / "checkpoint.bin"))
    with pytest.raises(rpyfmm.Error, match="dt") as caught:
        rpyfmm.mpi.run_bd(COMM, CHAINS.replace("dt = 0.002", "dt = -1.0"), out_dir=str(root / "never"))
    messages = COMM.allgather(str(caught.value))
    assert whole["ranks"] == SIZE and whole["last_step"] == 40 and resumed["last_step"] == 40
    assert all(m == messages[0] for m in messages)
    if RANK == 0:
        serial = (root / "serial" / "trajectory.xyz").read_bytes()
        assert (root / "ranks" / "trajectory.xyz").read_bytes() == serial
        assert (root / "half" / "trajectory.xyz").read_bytes() == serial
        assert not (root / "never").exists()
