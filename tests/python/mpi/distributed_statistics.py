"""What rpyfmm.mpi's operators report of their exchanges and work, and the options that steer them
(docs/mpi.md, "Python (mpi4py)"): the samplers' inner products (`inner_products`), the operators'
`communication`, `counts`, `exchange_counts` and sizes, checked against what the exchanges must
carry, the same on every rank where the ranks take the same steps, and against the serial
samplers' iteration counts; the Laplace FMM's measured partition weights and the distributed
FmmRpy's separation and cell capacity, within the FMMs' tolerance of direct sums.

Run by ctest under mpirun on 1, 2 and 3 ranks (tests/mpi/CMakeLists.txt):
`mpirun -n 2 python -m pytest tests/python/mpi/distributed_statistics.py`. Its name does not match
test_*.py, so that a plain pytest run of tests/python does not collect it.

The tests run in the same order on every rank and each one's collective calls all precede its
asserts, so that a failing assert on one rank cannot leave another waiting in a collective.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("mpi4py.MPI", reason="rpyfmm.mpi needs mpi4py")

import rpyfmm  # noqa: E402
import rpyfmm.mpi  # noqa: E402
from conftest import rel_err, suspension  # noqa: E402
from mpi_shares import COMM, RANK, SIZE, raised_on_every_rank  # noqa: E402
from mpi_shares import share_without_first as share  # noqa: E402

DOUBLE = 8  # bytes


def system(n: int, seed: int):
    """Positions (n, 3) of a jittered lattice with a few overlapping pairs, radii in [0.8, 1.2]."""
    x = suspension(n, seed=seed)
    return x, np.random.default_rng(seed + 1).uniform(0.8, 1.2, n)


def same_everywhere(value) -> bool:
    """Whether every rank holds `value` (collective)."""
    values = COMM.allgather(value)
    return all(v == values[0] for v in values)


def sane_seconds(seconds: float) -> bool:
    return math.isfinite(seconds) and seconds >= 0.0


@pytest.mark.parametrize("kind", ["direct", "fmm"])
def test_sampler_inner_products(kind: str) -> None:
    x, a = system(200 if kind == "direct" else 120, seed=21)
    part = share(len(x))
    z = rpyfmm.normal_noise(len(x), 5)
    op = {
        "direct": lambda: rpyfmm.mpi.DistributedDirectRpy(COMM, viscosity=0.8),
        "fmm": lambda: rpyfmm.mpi.DistributedFmmRpy(COMM, viscosity=0.8, tolerance=1e-8),
    }[kind]()
    before = op.inner_products
    op.set_positions(x[part], a[part])
    runs = {}
    keywords = {
        "lanczos": dict(tolerance=1e-6),
        "lanczos without reorthogonalization": dict(tolerance=1e-6, reorthogonalize=False),
        "chebyshev": dict(method="chebyshev", tolerance=1e-4),
    }
    for label, options in keywords.items():
        _, report = op.apply_sqrt(z[part], **options)
        runs[label] = (report.iterations, op.inner_products)
        if label == "chebyshev":  # the products of its bound estimate's Lanczos steps
            estimate_steps = report.operator_applications - report.iterations
    block = np.stack([z, rpyfmm.normal_noise(len(x), 6), rpyfmm.normal_noise(len(x), 7)])
    _, block_report = op.apply_sqrt_block(block[:, part, :], tolerance=1e-6)
    runs["block"] = (block_report.iterations, op.inner_products)
    _, _, rotation_report = op.apply_sqrt_rotation(z[part], 0.5 * z[part], tolerance=1e-6)
    rotation = op.inner_products
    # The block preconditioner twice on one configuration: built, then kept with the operator.
    blocked = []
    for _ in range(2):
        _, report = op.apply_sqrt(z[part], tolerance=1e-6, preconditioner="block", preconditioner_block=16)
        blocked.append((report, op.inner_products["blocks"]))
    n = part.stop - part.start
    serial_iterations = None
    if kind == "direct":
        serial = rpyfmm.DirectRpy(viscosity=0.8)
        serial.set_positions(x, a)
        serial_iterations = serial.apply_sqrt(z, tolerance=1e-6)[1].iterations

    assert before is None
    exchanges = {label: stats["exchanges"] for label, (_, stats) in runs.items()}
    # Every rank takes the same Lanczos steps (global inner products), so the same exchanges.
    assert same_everywhere(exchanges), exchanges
    for label, (iterations, stats) in runs.items():
        assert set(stats) == {"seconds", "exchanges", "blocks"} and sane_seconds(stats["seconds"]), (label, stats)
        # Without the block preconditioner its statistics are all zero (rpyfmm/mpi/sqrt.hpp).
        b = stats["blocks"]
        assert not b["reused"] and b["build_seconds"] == 0 and b["gather_bytes_received"] == 0, (label, b)
        assert all(b[k]["applications"] == 0 for k in ("apply_g", "apply_g_transpose", "solve_g")), (label, b)
    # rpyfmm/mpi/sqrt.hpp, InnerProductStats: the start and three exchanges per Lanczos step with
    # reorthogonalization, two without; with several columns those of the column with the most
    # steps (the report's iterations, the largest over the columns).
    for label in ("lanczos", "block"):
        assert exchanges[label] == 1 + 3 * runs[label][0], (label, runs[label])
    without = runs["lanczos without reorthogonalization"]
    assert exchanges["lanczos without reorthogonalization"] == 1 + 2 * without[0], without
    # Chebyshev's only inner products are the bound estimate's Lanczos steps (with
    # reorthogonalization; measured 30 steps, 91 exchanges, on 1-4 ranks).
    assert estimate_steps > 0 and exchanges["chebyshev"] == 1 + 3 * estimate_steps
    # The rotation sampler counts its exchanges as the translational one.
    assert rotation["exchanges"] == 1 + 3 * rotation_report.iterations and sane_seconds(rotation["seconds"])
    assert rotation_report.iterations > 0
    if serial_iterations is not None:  # the serial sampler's steps (docs/mpi.md, "Brownian displacements")
        assert runs["lanczos"][0] == serial_iterations
    # rpyfmm/mpi/sqrt.hpp, BlockPreconditionerStats: the first call builds the blocks by the
    # distributed bisection, whose bytes include 6 doubles (index, block, position, radius) per
    # member received from another rank (none on one rank); the second reuses the blocks, no build.
    # Each application of G moves 3 doubles per column and per particle sent or received.
    (first_report, first), (second_report, second) = blocked
    assert not first["reused"] and second["reused"]
    if SIZE == 1:
        assert first["gather_bytes_received"] == 0
    else:
        members = 6 * DOUBLE * first["particles_received"]
        assert first["gather_bytes_received"] >= members and first["gather_bytes_received"] > 0
    assert second["gather_bytes_received"] == 0 and second["build_seconds"] == 0
    for report, b in blocked:
        g = b["apply_g"]
        assert g["applications"] == report.operator_applications > 0
        assert g["bytes_received"] == 3 * DOUBLE * g["columns"] * (b["particles_sent"] + b["particles_received"])
        assert all(sane_seconds(b[k]["seconds"]) for k in ("apply_g", "apply_g_transpose", "solve_g"))
    assert first["particles_sent"] == second["particles_sent"]


def test_direct_communication() -> None:
    x, a = system(333, seed=19)
    part = share(len(x))
    n = part.stop - part.start
    f = np.random.default_rng(3).standard_normal((len(x), 3))
    op = rpyfmm.mpi.DistributedDirectRpy(COMM)
    before, counts_before = op.communication, op.counts
    op.set_positions(x[part], a[part])
    op.apply(f[part])
    after_apply = op.communication
    op.apply_block(np.stack([f[part], 2 * f[part]]))
    after_block = op.communication
    counts = op.counts
    all_counts = COMM.allgather(n)

    assert all(v == 0 for v in before.values()) and len(counts_before) == 0
    assert counts.dtype == np.uint64 and list(counts) == all_counts
    # tests/mpi/test_distributed_direct.cpp and test_distributed_direct_block.cpp: the other ranks'
    # source blocks pass once per product, 7 doubles per particle (position, radius, force), with
    # nrhs columns 4 + 3 nrhs.
    assert after_apply["apply_bytes_received"] == 7 * DOUBLE * (len(x) - n)
    assert after_block["apply_bytes_received"] == (4 + 3 * 2) * DOUBLE * (len(x) - n)
    for stats in (after_apply, after_block):
        assert all(sane_seconds(stats[k]) for k in ("set_positions_seconds", "apply_seconds", "applies_seconds"))
    # applies_seconds sums every product's apply_seconds since set_positions.
    assert after_block["applies_seconds"] >= after_block["apply_seconds"]
    assert after_block["applies_seconds"] >= after_apply["applies_seconds"]


def test_fmm_communication() -> None:
    x, a = system(150, seed=23)
    part = share(len(x))
    f = np.random.default_rng(4).standard_normal((len(x), 3))
    op = rpyfmm.mpi.DistributedFmmRpy(COMM, tolerance=1e-6)
    op.set_positions(x[part], a[part])
    op.apply(f[part])
    s, far = op.communication, op.laplace_communication
    halo, counts = op.halo_size, op.counts
    halo_total = COMM.allreduce(halo)
    n = part.stop - part.start

    assert list(counts) == COMM.allgather(n)
    # tests/mpi/test_distributed_fmm_rpy_stats.cpp: the halo particles arrive with the Laplace
    # FMM's halo; radii differ, so set_positions sends one double per owned and per halo particle;
    # each product returns this rank's near velocities (3 doubles per particle, its own share
    # counted), and its total is the Laplace FMM's evaluation plus that.
    assert halo == far["halo_received"]
    assert s["near_set_positions_bytes_received"] == (op.owned_size + halo) * DOUBLE
    assert s["near_apply_bytes_received"] == n * 3 * DOUBLE
    assert s["apply_bytes_received"] == far["evaluate_bytes_received"] + s["near_apply_bytes_received"]
    assert COMM.allreduce(op.owned_size) == len(x)
    if SIZE == 1:
        assert halo_total == 0
    assert all(sane_seconds(v) for k, v in s.items() if k.endswith("seconds"))
    assert (s["near_sums_seconds"] > 0) == (op.owned_size > 0)  # the near sums' own work
    assert set(far["evaluate_seconds"]) >= {"charges", "essential", "results"}


def test_laplace_communication() -> None:
    x = np.random.default_rng(8).uniform(0, 10, (400, 3))
    part = share(len(x))
    n = part.stop - part.start
    q = np.random.default_rng(9).standard_normal(len(x))
    fmm = rpyfmm.mpi.DistributedLaplaceFmm(COMM, tolerance=1e-6)
    fmm.set_points(x[part])
    fmm.evaluate(q[part])
    c = fmm.communication
    owned, essential, owned_targets = fmm.owned_size, fmm.essential_size, fmm.owned_target_size
    totals = COMM.allreduce(np.array([owned, c["halo_sent"], c["halo_received"], c["nodes_sent"],
                                      c["nodes_received"], c["cells_sent"], c["cells_received"]]))
    separation = fmm.separation
    regions = COMM.allreduce(np.array([c["region_neighbours"], c["region_sent_to"]]))

    # tests/mpi/test_distributed_fmm.cpp: every source owned once, what is sent is received, the
    # serial FMM's sources owned + halo + equivalent nodes, and the bytes of an evaluation of one
    # density with every output: its charges (owned, halo and nodes) and this rank's 10 results
    # per source.
    assert totals[0] == len(x) and owned_targets == owned
    assert totals[1] == totals[2] and totals[3] == totals[4] and totals[5] == totals[6]
    assert essential == (0 if owned == 0 else owned + c["halo_received"] + c["nodes_received"])
    assert c["evaluate_bytes_received"] == DOUBLE * (owned + c["halo_received"] + c["nodes_received"]) + \
        DOUBLE * 10 * n
    assert set(c["evaluate_seconds"]) == {"charges", "essential", "results"}
    assert all(sane_seconds(v) for stage in ("plan_seconds", "evaluate_seconds", "compute_seconds")
               for v in c[stage].values())
    assert separation >= 1.0 and same_everywhere(separation)
    # The regions' covers (docs/mpi.md, "Distributed Laplace FMM"): each sent once and received
    # once, from at most every other rank, 48 bytes per box.
    assert regions[0] == regions[1] and c["region_neighbours"] <= SIZE - 1
    assert c["region_bytes_received"] % 48 == 0 and c["region_boxes"] >= (1 if owned else 0)


def test_pse_exchange_counts() -> None:
    x = suspension(120, seed=31)
    part = share(len(x))
    op = rpyfmm.mpi.DistributedPseRpy(COMM, box=20.0, tolerance=1e-3)
    with pytest.raises(rpyfmm.Error):
        _ = op.memory_bytes  # before set_positions (not collective: a local check)
    op.set_positions(x[part], 1.0)
    c, memory = op.exchange_counts, op.memory_bytes
    sent, received = COMM.allreduce(c["wave_sent"]), COMM.allreduce(c["wave_received"])

    assert set(c) == {"wave_sent", "wave_received", "halo_received"}
    # Every position sent to another rank's slab is received there; on one rank nothing moves.
    assert sent == received
    if SIZE == 1:
        assert c == {"wave_sent": 0, "wave_received": 0, "halo_received": 0}
    else:
        assert sent > 0
    assert memory > 0


def test_pse_communication() -> None:
    x = suspension(120, seed=32)
    part = share(len(x))
    op = rpyfmm.mpi.DistributedPseRpy(COMM, box=20.0, tolerance=1e-3)
    op.set_positions(x[part], 1.0)
    fresh, c = op.communication, op.exchange_counts
    _ = op.apply(np.ones_like(x[part]))
    after = op.communication

    assert set(fresh) == {"set_positions_seconds", "apply_seconds", "apply_bytes_received", "applies_seconds"}
    assert fresh["applies_seconds"] == 0.0 and fresh["apply_bytes_received"] == 0
    assert sane_seconds(fresh["set_positions_seconds"]) and sane_seconds(after["apply_seconds"])
    # Three doubles per particle each exchange carries from another rank: forces to the slabs and
    # the halo, velocities back from the slabs.
    assert after["apply_bytes_received"] == DOUBLE * 3 * (c["wave_received"] + c["wave_sent"] + c["halo_received"])
    assert after["applies_seconds"] == after["apply_seconds"]


def test_laplace_measured_weights() -> None:
    rng = np.random.default_rng(12)
    # Half the sources in a small cluster: leaves of very different cost.
    x = np.vstack([rng.uniform(0, 10, (1000, 3)), rng.uniform(4, 5, (1000, 3))])[rng.permutation(2000)]
    q = rng.standard_normal(len(x))
    part = share(len(x))
    last = RANK == SIZE - 1
    fmm = rpyfmm.mpi.DistributedLaplaceFmm(COMM, tolerance=1e-6)
    fmm.set_points(x[part])
    first = fmm.evaluate(q[part])
    w = fmm.measured_weights()
    fmm.set_points(x[part], None, w)
    weighted = fmm.evaluate(q[part])
    owned = COMM.allreduce(fmm.owned_size)
    bad_w = w.copy()
    if last:
        bad_w[0] = np.nan
    messages = [
        raised_on_every_rank(lambda: fmm.set_points(x[part], None, bad_w)),
        raised_on_every_rank(lambda: fmm.set_points(x[part], None, w[:-1] if last else w)),
        raised_on_every_rank(lambda: fmm.set_points(x[part], None, w.reshape(-1, 1) if last else w),
                             rpyfmm.InvalidInputError),
    ]
    fmm.set_points(x[part], x[part][:5])  # results at targets: no measured weights
    messages.append(raised_on_every_rank(fmm.measured_weights, rpyfmm.NotSupportedError))
    exact = rpyfmm.laplace_direct(x, q)
    total = COMM.allreduce(float(np.sum(w)))

    assert w.shape == (part.stop - part.start,) and np.all(np.isfinite(w)) and np.all(w >= 0)
    assert total > 0 and owned == len(x)
    # The contract (docs/mpi.md, "Distributed Laplace FMM"): relative l2 error of each output at
    # most the tolerance, whatever the partition the weights give.
    for r in (first, weighted):
        r = np.concatenate(COMM.allgather(r))
        for cols in (slice(0, 1), slice(1, 4), slice(4, 10)):
            assert rel_err(r[:, cols], exact[:, cols]) <= 1e-6
    for ranks in messages:
        assert all(m == ranks[0] for m in ranks), ranks
        assert f"rank {SIZE - 1} of {SIZE}" in ranks[0] or "measured weights" in ranks[0], ranks[0]
    assert "weights has shape" in messages[2][0]


def test_fmm_exchange_options() -> None:
    x, a = system(150, seed=27)
    part = share(len(x))
    f = np.random.default_rng(5).standard_normal((len(x), 3))
    default = rpyfmm.mpi.DistributedFmmRpy(COMM, tolerance=1e-6)
    op = rpyfmm.mpi.DistributedFmmRpy(COMM, tolerance=1e-6, separation=3.0, cell_capacity=16)
    op.set_positions(x[part], a[part])
    u = np.concatenate(COMM.allgather(op.apply(f[part])))
    refused = raised_on_every_rank(lambda: rpyfmm.mpi.DistributedFmmRpy(COMM, separation=0.5),
                                   rpyfmm.InvalidArgumentError)
    serial = rpyfmm.DirectRpy()
    serial.set_positions(x, a)

    assert default.separation == 2.0 and op.separation == 3.0
    # The FMM's contract: relative l2 error of U at most the tolerance, whatever the acceptance
    # ratio and cell capacity of the essential tree's exchange.
    assert rel_err(u, serial.apply(f)) <= 1e-6
    assert all(m == refused[0] for m in refused) and "separation" in refused[0]
