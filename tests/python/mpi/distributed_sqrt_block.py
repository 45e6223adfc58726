"""rpyfmm.mpi's samplers with several right-hand sides (apply_sqrt_block of DistributedDirectRpy
and DistributedFmmRpy; docs/mpi.md, "Several right-hand sides" and "Python (mpi4py)"): each column
against the one-column sampler on that column, the gathered columns against the serial
DirectRpy.apply_sqrt_block on the whole set, and bad shapes on one rank.

Run by ctest under mpirun on 1, 2 and 3 ranks (tests/mpi/CMakeLists.txt):
`mpirun -n 2 python -m pytest tests/python/mpi/distributed_sqrt_block.py`. Its name does not match
test_*.py, so that a plain pytest run of tests/python does not collect it.

The tests run in the same order on every rank and each one's collective calls all precede its
asserts, so that a failing assert on one rank cannot leave another waiting in a collective.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("mpi4py.MPI", reason="rpyfmm.mpi needs mpi4py")

import rpyfmm  # noqa: E402
import rpyfmm.mpi  # noqa: E402
from conftest import suspension  # noqa: E402
from mpi_shares import COMM, RANK, SIZE, raised_on_every_rank  # noqa: E402
from mpi_shares import share_without_first as share  # noqa: E402

NRHS = 3


def columns(n: int) -> np.ndarray:
    """NRHS standard normal columns (NRHS, n, 3), the same on every rank."""
    return np.stack([rpyfmm.normal_noise(n, 40 + c) for c in range(NRHS)])


def gathered_columns(w: np.ndarray) -> np.ndarray:
    """The ranks' (NRHS, n, 3) blocks joined along the particles in rank order, on every rank."""
    return np.concatenate(COMM.allgather(w.reshape(NRHS, -1, 3)), axis=1)


@pytest.mark.parametrize(
    "method, preconditioner", [("lanczos", "none"), ("chebyshev", "none"), ("lanczos", "block")]
)
@pytest.mark.parametrize("flat", [False, True])
def test_direct_columns_are_singles_and_the_serial_block_sample(
    method: str, preconditioner: str, flat: bool
) -> None:
    x = suspension(200, seed=21)
    a = np.random.default_rng(22).uniform(0.8, 1.2, len(x))
    z = columns(len(x))
    # docs/mpi.md, "Several right-hand sides": every inner product is summed in the serial order and
    # the block preconditioner's blocks are the serial ones of the whole set, whatever the partition.
    part = share(len(x))
    keywords = dict(method=method, preconditioner=preconditioner, tolerance=1e-6)
    op = rpyfmm.mpi.DistributedDirectRpy(COMM, viscosity=0.7)
    op.set_positions(x[part], a[part])
    local = z[:, part, :]
    if flat:
        local = local.reshape(NRHS, -1)
    w, report = op.apply_sqrt_block(local, **keywords)
    again, _ = op.apply_sqrt_block(local, **keywords)
    singles = [op.apply_sqrt(local[c], **keywords) for c in range(NRHS)]
    out = np.empty_like(local)
    same_out, _ = op.apply_sqrt_block(local, out=out, **keywords)
    serial = rpyfmm.DirectRpy(viscosity=0.7)
    serial.set_positions(x, a)
    w_serial, report_serial = serial.apply_sqrt_block(z, **keywords)
    whole = gathered_columns(w)
    # rpyfmm/mpi/sqrt.hpp: column c equals the sampler on column c alone bit for bit, and (the
    # serial summation order) the serial block sampler's columns bit for bit.
    assert w.shape == local.shape and np.array_equal(again, w)
    assert all(np.array_equal(w[c], singles[c][0]) for c in range(NRHS))
    assert report.iterations == max(s[1].iterations for s in singles)
    assert same_out is out and np.array_equal(out, w)
    assert np.array_equal(whole, w_serial)
    assert report.iterations == report_serial.iterations
    assert report.vector_products == report_serial.vector_products


def test_fmm_columns_are_singles() -> None:
    x = suspension(240, seed=23)
    z = columns(len(x))
    part = share(len(x))
    op = rpyfmm.mpi.DistributedFmmRpy(COMM, viscosity=0.7, tolerance=1e-8)
    op.set_positions(x[part], 1.0)
    local = z[:, part, :]
    w, report = op.apply_sqrt_block(local, tolerance=1e-6)
    singles = [op.apply_sqrt(local[c], tolerance=1e-6)[0] for c in range(NRHS)]
    # rpyfmm/mpi/sqrt.hpp: DistributedFmmRpy.apply_block is apply on every column bit for bit, so
    # each column is the one-column sampler's bit for bit.
    assert all(np.array_equal(w[c], singles[c]) for c in range(NRHS))
    assert report.iterations > 0


@pytest.mark.parametrize("kind", ["direct", "fmm"])
def test_bad_shapes_raise_on_every_rank(kind: str) -> None:
    x = suspension(60, seed=24)
    z = columns(len(x))
    part = slice(0, len(x)) if SIZE == 1 else share(len(x))
    op = {
        "direct": lambda: rpyfmm.mpi.DistributedDirectRpy(COMM),
        "fmm": lambda: rpyfmm.mpi.DistributedFmmRpy(COMM, tolerance=1e-6),
    }[kind]()
    op.set_positions(x[part], 1.0)
    local = z[:, part, :]
    last = RANK == SIZE - 1
    messages = [
        # One flat column (3n,) instead of a block, on the last rank.
        raised_on_every_rank(lambda: op.apply_sqrt_block(local[0].ravel() if last else local),
                             rpyfmm.InvalidInputError),
        # Columns one particle short, on the last rank (the C++ sampler's collective size check).
        raised_on_every_rank(lambda: op.apply_sqrt_block(local[:, :-1] if last else local)),
        # No column at all, on every rank.
        raised_on_every_rank(lambda: op.apply_sqrt_block(local[:0])),
    ]
    if SIZE > 1:
        # A different number of columns on the last rank.
        messages.append(raised_on_every_rank(lambda: op.apply_sqrt_block(local[:2] if last else local)))
    w, _ = op.apply_sqrt_block(local)  # and the operator works after each failure
    for ranks in messages:
        assert all(m == ranks[0] for m in ranks)
    assert f"rank {SIZE - 1} of {SIZE}" in messages[0][0] and "expected (nrhs, N, 3)" in messages[0][0]
    assert np.all(np.isfinite(w))
