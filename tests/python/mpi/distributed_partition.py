"""rpyfmm.mpi.SfcPartition: the Morton-curve partition of particles the ranks hold, against keys
computed here from the documented formula, the balance bound, and the moves of data to the owners
and back; the Hilbert curve's order against the octree cells of the same formula (docs/mpi.md, "Space-filling-curve partition" and "Python (mpi4py)").

Run by ctest under mpirun with distributed_bd.py (tests/mpi/CMakeLists.txt):
`mpirun -n 3 python -m pytest tests/python/mpi/distributed_partition.py`. Its name does not match
test_*.py, so that a plain pytest run of tests/python does not collect it.

The tests run in the same order on every rank and each one's collective calls all precede its
asserts, so that a failing assert on one rank cannot leave another waiting in a collective.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

MPI = pytest.importorskip("mpi4py.MPI", reason="rpyfmm.mpi needs mpi4py")

import rpyfmm  # noqa: E402
import rpyfmm.mpi  # noqa: E402
from distributed_operators import share  # noqa: E402

COMM = MPI.COMM_WORLD
RANK, SIZE = COMM.Get_rank(), COMM.Get_size()
N = 500


def cloud() -> tuple[np.ndarray, np.ndarray]:
    """N positions in a box and weights in [0, 3), the same on every rank."""
    rng = np.random.default_rng(21)
    return rng.uniform(-5.0, 20.0, (N, 3)), rng.uniform(0.0, 3.0, N)


def morton_keys(x: np.ndarray) -> np.ndarray:
    """The keys of partition.hpp: cell floor((c/2 - o/2) / h 2^21) per axis (the upper face in the
    last cell) in the cube of origin o (smallest coordinate per axis) and half side h (half the
    largest extent), bit b of the x, y, z cells becoming bit 3b + 2, 3b + 1, 3b of the key."""
    origin = x.min(axis=0)
    half = (x.max(axis=0) - origin).max() / 2.0
    keys = np.zeros(len(x), dtype=np.uint64)
    for i, p in enumerate(x):
        cells = [min(math.floor((p[c] / 2 - origin[c] / 2) / half * 2.0**21), 2**21 - 1) for c in range(3)]
        key = 0
        for b in range(21):
            for axis, cell in enumerate(cells):
                key |= ((cell >> b) & 1) << (3 * b + 2 - axis)
        keys[i] = key
    return keys


def test_owned_particles_are_the_balanced_morton_ranges() -> None:
    x, w = cloud()
    part_slice = share(N)
    part = rpyfmm.mpi.SfcPartition(COMM, x[part_slice], w[part_slice])
    indices, keys = part.owned_indices, part.owned_keys
    owned = COMM.allgather((indices, keys))
    counts, weights, splitters = part.owned_counts, part.owned_weights, part.splitters
    assert part.input_size == len(x[part_slice]) and part.global_size == N
    assert part.owned_size == len(indices) and list(counts) == [len(i) for i, _ in owned]
    assert splitters.shape == (SIZE - 1, 2)
    all_indices = np.concatenate([i for i, _ in owned])
    assert np.array_equal(np.sort(all_indices), np.arange(N))
    # The keys are those of the documented formula, and the ranks' ranges follow one another in
    # (key, index) order, cut at the splitters.
    expected = morton_keys(x)
    order = sorted(zip(expected.tolist(), range(N)))
    assert list(zip(np.concatenate([k for _, k in owned]).tolist(), all_indices.tolist())) == order
    for r in range(1, SIZE):
        first = owned[r][0][0] if len(owned[r][0]) else None
        if first is not None:
            assert (int(owned[r][1][0]), int(first)) >= tuple(int(v) for v in splitters[r - 1])
    # The cuts bound every part by ceil(Q / P) + max q_i; in the weights' units, with the rounding
    # of each weight to 2^-(62 - ceil(log2 N)) of the largest, a relative 1e-12 of the total.
    assert np.isclose(weights.sum(), w.sum(), rtol=1e-12)
    assert weights.max() <= w.sum() / SIZE + w.max() + 1e-12 * w.sum()
    assert part.imbalance == pytest.approx(weights.max() / weights.mean(), rel=1e-12)
    origin, side = part.cube
    assert np.array_equal(origin, x.min(axis=0)) and side == (x.max(axis=0) - x.min(axis=0)).max()


def test_owned_set_does_not_depend_on_the_input_distribution() -> None:
    x, _ = cloud()
    uneven = rpyfmm.mpi.SfcPartition(COMM, x[share(N)])
    empty_first = rpyfmm.mpi.SfcPartition(COMM, x[share(N, empty_first=True)].reshape(-1))
    assert np.array_equal(uneven.owned_indices, empty_first.owned_indices)


def test_moves_to_the_owners_and_back_bit_for_bit() -> None:
    x, w = cloud()
    mine = share(N, empty_first=True)
    part = rpyfmm.mpi.SfcPartition(COMM, x[mine])
    values = np.random.default_rng(RANK).standard_normal((part.input_size, 5))
    values[:1, 0] = [-0.0] if part.input_size else values[:1, 0]
    owned_x = part.to_owners(x[mine])
    owned_w = part.to_owners(w[mine])
    moved = part.to_owners(values)
    back = part.to_origin(moved)
    back_w = part.to_origin(owned_w)
    assert owned_x.shape == (part.owned_size, 3) and owned_w.shape == (part.owned_size,)
    assert np.array_equal(owned_x, x[part.owned_indices.astype(np.int64)])
    assert np.array_equal(owned_w, w[part.owned_indices.astype(np.int64)])
    assert back.tobytes() == values.tobytes() and back_w.tobytes() == w[mine].tobytes()


def test_hilbert_order_keeps_the_octree_cells_contiguous() -> None:
    x, w = cloud()
    part = rpyfmm.mpi.SfcPartition(COMM, x[share(N)], w[share(N)], curve="hilbert")
    morton = rpyfmm.mpi.SfcPartition(COMM, x[share(N)], curve="morton")
    owned = COMM.allgather((part.owned_indices, part.owned_keys))
    indices = np.concatenate([i for i, _ in owned]).astype(np.int64)
    keys = np.concatenate([k for _, k in owned])
    assert part.curve == "hilbert" and morton.curve == "morton"
    assert np.array_equal(np.sort(indices), np.arange(N))
    assert list(zip(keys.tolist(), indices.tolist())) == sorted(zip(keys.tolist(), indices.tolist()))
    # On either curve a key's first 3l bits name one octree cell of level l (partition.hpp): the
    # particles sharing a prefix are exactly those sharing the Morton prefix, the cell computed here
    # from the documented formula, for every level.
    cells = morton_keys(x)[indices]
    for level in (1, 2, 3, 5, 8, 21):
        shift = np.uint64(3 * (21 - level))
        by_key = {}
        for k, c in zip((keys >> shift).tolist(), (cells >> shift).tolist()):
            by_key.setdefault(k, set()).add(c)
        assert all(len(c) == 1 for c in by_key.values())
        assert len(by_key) == len(set((cells >> shift).tolist()))
    # The curves differ: the octants of level 1 come in Morton's z-order on one, in a Gray-code
    # order on the other.
    first_octants = [int(c) for c in dict.fromkeys((cells >> np.uint64(60)).tolist())]
    assert sorted(first_octants) == list(range(8)) and first_octants != list(range(8))
    # The balance bound of the cuts is the curve's too (as test_owned_particles_are_the_balanced_morton_ranges).
    weights = part.owned_weights
    assert weights.max() <= w.sum() / SIZE + w.max() + 1e-12 * w.sum()


def test_bad_input_on_one_rank_raises_on_every_rank() -> None:
    x, w = cloud()
    mine = x[share(N)].copy()
    if RANK == SIZE - 1 and len(mine):
        mine[0, 1] = np.nan
    with pytest.raises(rpyfmm.Error, match="NaN") as nan:
        rpyfmm.mpi.SfcPartition(COMM, mine)
    part = rpyfmm.mpi.SfcPartition(COMM, x[share(N)])
    rows = x[share(N)] if RANK != SIZE - 1 else np.zeros((part.input_size + 1, 3))
    with pytest.raises(rpyfmm.Error) as short:
        part.to_owners(rows)
    cube = np.zeros((part.input_size, 1, 3)) if RANK == 0 else x[share(N)]
    with pytest.raises(rpyfmm.InvalidInputError, match="expected") as ndim:
        part.to_owners(cube)
    bad_shape = x[share(N)][:, :2] if RANK == 0 else x[share(N)]
    with pytest.raises(rpyfmm.InvalidInputError, match="positions") as shape:
        rpyfmm.mpi.SfcPartition(COMM, bad_shape)
    moved = part.to_owners(x[share(N)])  # usable after the failures
    for caught in (nan, short, ndim, shape):
        messages = COMM.allgather(str(caught.value))
        assert all(m == messages[0] for m in messages), messages
    assert moved.shape == (part.owned_size, 3)
