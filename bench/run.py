#!/usr/bin/env python3
"""Benchmark driver: builds the benchmark programs, runs them, writes bench/results/<group>.json and
renders bench/README.md from those files.

    python3 bench/run.py [--quick|--full|--isa-rows] [--only GROUP ...] [--compare COMMIT] [--simd-levels]
                         [--levels L ...] [--concurrent] [--build build/release] [--rounds R] [--no-build]
                         [--render-only]

Groups: fmm (Laplace FMM, and fmm3dpy's lfmm3d on the same points when it imports), direct (direct
kernels), rpy (RPY operators: FmmRpy, DirectRpy, and fmm3dpy's Stokes FMM stfmm3d on the same points
and forces when it imports), pse (PSE on the CPU), pse-gpu (PSE with CUDA, only
where a GPU is present), bd-gpu (the device BD engine at 1e6 particles and the CPU engine beside it,
only where a GPU is present), samplers (Lanczos, Chebyshev, block preconditioner), bd (BD steps), sac
(Tran et al. (2015)'s Table 4 alumina-silica systems), rigid (rigid-body mobility solves and steps),
mpi (the distributed FMM, direct RPY operator and free-draining BD on 1-4 ranks), mpi-block
(apply_block against single products of the distributed RPY operators on 1 and 2 ranks), mpi-fmm-rpy
(one product of the distributed FmmRpy on 1 and 2 ranks beside the serial FmmRpy), mpi-curve (the
distributed Laplace FMM partitioned along the Morton and the Hilbert curve on 2-4 ranks),
mpi-block-cache (the first block-preconditioned sample after set_positions against a second on 2
ranks), mpi-partition (SfcPartition's multi-way cuts' search against the bisection on 2 and 4 ranks),
mpi-bisection (the block preconditioner's blocks by the distributed bisection against the gather of the
whole set on 2 and 4 ranks), mpi-targets (separate targets of the distributed Laplace FMM partitioned by
their own cuts and by the sources' on 2 and 4 ranks).

Every case runs at 1 thread (the per-core figure) and at all cores; each program reports the median
of its own repetitions and the driver the median over --rounds runs. --compare COMMIT builds COMMIT in
a scratch worktree build/compare-<sha> (same preset) and runs every case on both builds in turn, so
machine noise hits both alike; --simd-levels runs every case at each instruction-set level the CPU
has (RPYFMM_SIMD, docs/reproducibility.md; --levels picks some, --isa-rows runs the sizes that page
quotes). Both write <group>.compare-<sha>.json or <group>.simd-levels.json next to the headline
files, and the page shows their ratios. --concurrent runs each one-thread case's rounds on every
variant at once, each on its own physical core (a machine with many cores: the variants then share
the memory system alike, and the rounds take the time of one).

fmm3dpy (the peer code of the fmm and rpy groups) is looked up in the virtual environment build/bench-venv:
    python3 -m venv --system-site-packages build/bench-venv && build/bench-venv/bin/pip install fmm3dpy
matplotlib, where it imports there or in this interpreter, draws bench/results/<group>.png.
"""
from __future__ import annotations

import argparse
import csv
import datetime
import io
import json
import os
import statistics
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results"
VENV_PYTHON = ROOT / "build" / "bench-venv" / "bin" / "python"
CORES = os.cpu_count() or 1
THREADS = sorted({1, CORES})


@dataclass
class Case:
    """One benchmark run: a program of the build's bench/ folder, its arguments, its thread count."""

    argv: list[str]
    threads: int
    key: dict  # what identifies the case in the tables (merged into every row it prints)
    keep: dict = field(default_factory=dict)  # only rows whose columns have these values
    peer: bool = False  # also run the group's fmm3dpy peer on the same points


@dataclass
class Variant:
    """A build and an instruction-set level every case runs on (several: side by side)."""

    name: str
    build: Path
    simd: str | None = None


# ----------------------------------------------------------------------------------------------
# Output parsing


def number(text: str):
    try:
        value = float(text)
    except ValueError:
        return text
    return int(value) if value.is_integer() and "e" not in text and "." not in text else value


def parse_csv(out: str) -> list[dict]:
    lines = [line for line in out.splitlines() if line and not line.startswith("#")]
    return [{k: number(v) for k, v in row.items()} for row in csv.DictReader(io.StringIO("\n".join(lines)))]


def parse_json_lines(out: str) -> list[dict]:
    rows = []
    for line in out.splitlines():
        if line.startswith("{"):
            row = json.loads(line)
            row.update({f"stage_{k}": v for k, v in row.pop("stages", {}).items()})
            for key in [k for k, v in row.items() if isinstance(v, dict)]:  # {"a": {"b": 1}} -> a_b
                row.update({f"{key}_{k}": v for k, v in row.pop(key).items()})
            rows.append(row)
    return rows


# ----------------------------------------------------------------------------------------------
# Groups: the cases of --quick and --full, how to read their output, what the page shows


@dataclass
class Peer:
    """fmm3dpy on the points (and charges or forces) a benchmark program writes to a file."""

    script: str  # Python source; argv: the file, N, eps, sampled targets, timed calls; prints one JSON line
    points_argv: object  # (case argv, file) -> the argv that makes the program write its points there
    ours: tuple  # our columns whose sum the peer's time (setup included) is divided by
    reps: object  # (case) -> timed calls of the peer (the median is reported)
    samples: int  # sampled targets of its error, as many as the group's own error has


@dataclass
class Group:
    name: str
    title: str
    about: str
    targets: list[str]
    cases: object  # (mode: "quick" | "full" | "isa") -> list[Case]
    parse: object = parse_csv
    time_key: str = ""  # the column compared between variants (seconds, lower is better)
    columns: list = field(default_factory=list)  # (header, column, format)
    keys: tuple = ()  # the columns that identify a row (the others are measured)
    needs_gpu: bool = False
    peer: Peer | None = None  # fmm3dpy on the same points, where it imports (cases with peer=True)


def fmm_cases(mode: str) -> list[Case]:
    if mode == "isa":
        return [Case(["fmm/bench_fmm", "--n", "1e6", "--dist", "cube", "--eps", "1e-6", "--reps", "3", "--sample", "500"],
                     1, {"N": 1000000, "dist": "cube", "eps": "1e-6"})]
    full = mode == "full"
    sizes, dists, epss = (["1e5", "1e6"], ["cube", "sphere"], ["1e-3", "1e-6", "1e-9"]) if full else (
        ["1e5"], ["cube"], ["1e-3", "1e-6"])
    return [Case(["fmm/bench_fmm", "--n", n, "--dist", d, "--eps", e, "--reps", "3", "--sample", "500"], t,
                 {"N": int(float(n)), "dist": d, "eps": e}, peer=True)
            for n in sizes for d in dists for e in epss for t in THREADS]


def direct_cases(mode: str) -> list[Case]:
    if mode == "isa":
        return [Case(["direct/bench_direct", "--n", "10000", "--threads", "1", "--reps", "3", "--kernel", "all"], 1, {})]
    n = "20000" if mode == "full" else "4000"
    return [Case(["direct/bench_direct", "--n", n, "--threads", str(t), "--reps", "5", "--kernel", "all"], t, {})
            for t in THREADS]


def rpy_cases(mode: str) -> list[Case]:
    if mode == "isa":
        return [Case(["rpy/bench_rpy_fmm", "suspension", "1000000", "1e-6", "1", "1"], 1, {})]
    full = mode == "full"
    dists, sizes, epss = (["suspension", "cylinder"], ["10000", "100000"], ["1e-3", "1e-6", "1e-9"]) if full else (
        ["suspension"], ["10000"], ["1e-3", "1e-6"])
    cases = [Case(["rpy/bench_rpy_fmm", d, n, e, str(t), "3"], t, {}, peer=True) for d in dists for n in sizes
             for e in epss for t in THREADS]
    # N = 1e6 at 1e-6, one thread: the automatic leaves and 100-point leaves (a tree one level
    # deeper, which suits products with torques, whose near field costs ~3x the force-only one).
    if full:
        cases.append(Case(["rpy/bench_rpy_fmm", "suspension", "1000000", "1e-6", "1", "1", "-", "0,100"], 1, {},
                          peer=True))
    else:
        # The RPY / Laplace ratio from 1e4 to 1e6 points at 1e-6, one thread (about 2 minutes a round,
        # 6.5 with the fmm3dpy peer: stfmm3d took 230 s at 1e6 on the 2-core development machine).
        cases += [Case(["rpy/bench_rpy_fmm", "suspension", n, "1e-6", "1", r], 1, {}, peer=True)
                  for n, r in (("100000", "3"), ("1000000", "1"))]
    return cases


def pse_cases(mode: str) -> list[Case]:
    if mode == "isa":
        return [Case(["pse/bench_pse", "--quick", "100000"], 1, {}, keep={"threads": 1})]
    sizes = ["8000", "32000", "128000"] if mode == "full" else ["8000", "32000"]
    # bench_pse times every thread count from 1 to OMP_NUM_THREADS; keep the one asked for.
    return [Case(["pse/bench_pse", "--quick", n], t, {}, keep={"threads": t}) for n in sizes for t in THREADS]


def pse_gpu_cases(mode: str) -> list[Case]:
    if mode == "isa":
        return []
    sizes = ["32000", "128000", "512000"] if mode == "full" else ["32000", "128000"]
    return [Case(["pse/bench_pse", "--cuda", *sizes], CORES, {})]


def bd_gpu_cases(mode: str) -> list[Case]:
    """The device BD engine at Tran et al. (2015)'s Tables 1-3 size (1e6 free-draining WCA spheres at
    phi = 0.15), each rebuild strategy, and the CPU engine on all host cores for the ratio."""
    if mode == "isa":
        return []
    steps = "100" if mode == "full" else "50"
    return [Case(["bd/bench_bd", "engine", "--engine", "cuda", "--n", "1e6", "--steps", steps], CORES, {}),
            Case(["bd/bench_bd", "engine", "--engine", "cpu", "--n", "1e6", "--steps", "10", "--strategies",
                  "dynamic"], CORES, {})]


def sampler_cases(mode: str) -> list[Case]:
    if mode == "isa":
        return []
    op, sizes, tols = ("fmm", "10000,100000", "1e-3,1e-5") if mode == "full" else ("direct", "2000", "1e-3")
    return [Case(["sqrt/bench_sqrt", op, sizes, tols, str(t), "3", "1e-6", "all", "noblock"], t, {})
            for t in THREADS]


def bd_cases(mode: str) -> list[Case]:
    if mode == "isa":
        return []
    full = mode == "full"
    sizes = {"direct": "1000,3000", "fmm": "3000,10000,30000", "pse": "3000,10000,30000"} if full else {
        "direct": "2000", "fmm": "2000", "pse": "2000"}
    return [Case(["bd/bench_bd", "steps", "--method", m, "--n", n, "--steps", "5" if full else "3"], t, {})
            for m, n in sizes.items() for t in THREADS]


def bd_open_cases(mode: str) -> list[Case]:
    """Free-space BD with HI at scale: PSE with open boundaries against the FMM + block-Lanczos path."""
    if mode == "isa":
        return []
    full = mode == "full"
    # direct at small N: the crossover of pse-open against exact sums with a dense-sized Lanczos.
    sizes = {"direct": "1000,3000", "fmm": "10000,100000", "pse-open": "1000,3000,10000,100000,1000000"} if full else {
        "direct": "1000", "fmm": "10000", "pse-open": "1000,10000,100000"}
    return [Case(["bd/bench_bd", "steps", "--method", m, "--n", n, "--steps", "3"], t, {})
            for m, n in sizes.items() for t in THREADS]


def sac_cases(mode: str) -> list[Case]:
    if mode == "isa":
        return []
    steps = "50" if mode == "full" else "20"
    return [Case(["bd/bench_bd", "sac-table4", "--scheme", scheme, "--steps", steps], t, {})
            for scheme in ("sac", "naive") for t in THREADS]


def rigid_cases(mode: str) -> list[Case]:
    if mode == "isa":
        return []
    full = mode == "full"
    # Direct bead operators at <= 4000 beads also time the dense reference: small counts only.
    counts = {"direct": "8,64", "fmm": "64,512", "step": "8,64"} if full else {
        "direct": "8", "fmm": "8,64", "step": "8"}
    subdivisions = "2" if full else "1"
    solves = [Case(["rigid/bench_rigid", op, counts[op], subdivisions, "0.1", "1e-6", "1e-6", "3", "noplain"], t,
                   {"benchmark": "solve"}) for op in ("direct", "fmm") for t in THREADS]
    steps = [Case(["rigid/bench_rigid_dynamics", "fmm", counts["step"], "1", "0.1", "3", "3", "1e-6"], t,
                  {"benchmark": "step"}) for t in THREADS]
    return solves + steps


def mpi_cases(mode: str) -> list[Case]:
    """DistributedLaplaceFmm, DistributedDirectRpy and DistributedBd on P = 1..4 ranks of one thread
    each (mpiexec --oversubscribe): strong scaling at fixed N, weak scaling at fixed N / P (bench/mpi)."""
    sizes = {"fmm": ("4e5", "1e5"), "direct": ("2e4", "5e3"), "bd": ("1e6", "2.5e5")} if mode == "full" else {
        "fmm": ("1e5", "2.5e4"), "direct": ("1e4", "2.5e3"), "bd": ("1e5", "2.5e4")}
    def overlap(method: str) -> list[str]:  # fmm: the split serial FMM timed alongside
        return ["--overlap-exchange", "1"] if method == "fmm" else []
    return [Case(["mpi/bench_mpi_ranks", str(p), f"bench_mpi_{method}", "--n", n, "--eps", "1e-6", "--scaling",
                  scaling, "--reps", "3", *overlap(method)], 1, {})
            for method, (strong, weak) in sizes.items() for scaling, n in (("strong", strong), ("weak", weak))
            for p in (1, 2, 3, 4)]


def mpi_block_cases(mode: str) -> list[Case]:
    """apply_block with 4 right-hand sides against 4 applies, DistributedDirectRpy and DistributedFmmRpy on
    1 and 2 ranks of one thread each (bench/mpi/bench_mpi_block)."""
    sizes = {"direct": "2e4", "fmm": "1e5"} if mode == "full" else {"direct": "1e4", "fmm": "5e4"}
    return [Case(["mpi/bench_mpi_ranks", str(p), "bench_mpi_block", "--method", method, "--n", n, "--nrhs", "4",
                  "--eps", "1e-6", "--reps", "3"], 1, {})
            for method, n in sizes.items() for p in (1, 2)]


def mpi_fmm_rpy_cases(mode: str) -> list[Case]:
    """One product of DistributedFmmRpy on 1 and 2 ranks of one thread each, the serial FmmRpy on the
    whole set beside it on rank 0 (bench/mpi/bench_mpi_fmm_rpy)."""
    n = "1e5" if mode == "full" else "2e4"
    return [Case(["mpi/bench_mpi_ranks", str(p), "bench_mpi_fmm_rpy", "--n", n, "--eps", "1e-6", "--reps", "3"], 1,
                 {}) for p in (1, 2)]


def mpi_curve_cases(mode: str) -> list[Case]:
    """DistributedLaplaceFmm with the Morton and the Hilbert partition (one program runs both) on 2, 3
    and 4 ranks of one thread each, uniform and clustered sources (bench/mpi/bench_mpi_curve)."""
    n, epss = ("4e5", ("1e-3", "1e-6")) if mode == "full" else ("4e4", ("1e-3",))
    return [Case(["mpi/bench_mpi_ranks", str(p), "bench_mpi_curve", "--n", n, "--eps", e, "--points", points,
                  "--reps", "3"], 1, {})
            for points in ("uniform", "clustered") for e in epss for p in (2, 3, 4)]


def mpi_block_cache_cases(mode: str) -> list[Case]:
    """The first and a second block-preconditioned mpi::sqrt_apply on the same positions, 2 ranks of one
    thread each (bench/mpi/bench_mpi_block_cache)."""
    sizes = {"direct": "2e4", "fmm": "1e5"} if mode == "full" else {"direct": "5e3", "fmm": "2e4"}
    return [Case(["mpi/bench_mpi_ranks", "2", "bench_mpi_block_cache", "--method", method, "--n", n, "--reps", "3"],
                 1, {}) for method, n in sizes.items()]


def mpi_partition_cases(mode: str) -> list[Case]:
    """One SfcPartition construction with the multi-way search against the bisection (one program runs
    both) on 2 and 4 ranks of one thread each (bench/mpi/bench_mpi_partition)."""
    sizes = ("1e5", "1e6") if mode == "full" else ("1e5",)
    return [Case(["mpi/bench_mpi_ranks", str(p), "bench_mpi_partition", "--n", n, "--reps", "5"], 1, {})
            for n in sizes for p in (2, 4)]


def mpi_bisection_cases(mode: str) -> list[Case]:
    """The block preconditioner's blocks by the distributed bisection against the gather of the whole
    set (one program runs both) on 2 and 4 ranks of one thread each (bench/mpi/bench_mpi_bisection)."""
    n = "1e5" if mode == "full" else "2e4"
    return [Case(["mpi/bench_mpi_ranks", str(p), "bench_mpi_bisection", "--n", n, "--order", order, "--reps", "5"],
                 1, {}) for order in ("slabs", "random") for p in (2, 4)]


def mpi_targets_cases(mode: str) -> list[Case]:
    """DistributedLaplaceFmm with separate targets partitioned by their own cuts and by the sources'
    (one program runs both) on 2 and 4 ranks of one thread each (bench/mpi/bench_mpi_targets)."""
    n = "4e5" if mode == "full" else "4e4"
    return [Case(["mpi/bench_mpi_ranks", str(p), "bench_mpi_targets", "--n", n, "--eps", "1e-6", "--points", points,
                  "--reps", "3"], 1, {}) for points in ("uniform", "clustered") for p in (2, 4)]


# ----------------------------------------------------------------------------------------------
# The fmm3dpy peers: scripts run in the interpreter that imports fmm3dpy, on the points a benchmark
# program wrote; what they share comes first.

PEER_COMMON = r"""
import sys, time, json, statistics, numpy as np, fmm3dpy
path, n, eps, nsample, reps = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5])


def timed(call):
    # Median wall time of reps calls and the last result; every call builds its own tree (setup included).
    times, out = [], None
    for _ in range(reps):
        t0 = time.perf_counter()
        out = call()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def rel(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


idx = np.random.default_rng(99).integers(0, n, size=min(nsample, n))  # the sampled targets
"""

# lfmm3d: potential, gradient and Hessian of the charges of bench_fmm --npy; errors against l3ddir.
LFMM3D_PEER = PEER_COMMON + r"""
x = np.load(path); q = np.load(path + ".charges.npy")[0].copy()
src = np.ascontiguousarray(x.T)
t, out = timed(lambda: fmm3dpy.lfmm3d(eps=eps, sources=src, charges=q, pg=3))
ref = fmm3dpy.l3ddir(sources=src, targets=np.ascontiguousarray(src[:, idx]), charges=q, pgt=3)
print(json.dumps({"fmm3d_s": t, "fmm3d_err_pot": rel(out.pot[idx], ref.pottarg),
                  "fmm3d_err_hess": rel(out.hess[:, idx], ref.hesstarg)}))
"""

# stfmm3d: the velocity of Stokeslets (ifppreg=1) with the forces of bench_rpy_fmm as strengths. Its
# error: against an exact Stokeslet sum at the sampled targets in FMM3D's normalisation,
# (I/r + r r^T/r^3) / (8 pi) (ours: 1/(8 pi eta), docs/theory/rpy.md Sec. 2; a constant factor the
# relative error does not see). numpy, not st3ddir: fmm3dpy 2.1.0's st3ddir evaluates at the sources
# whatever the targets.
STFMM3D_PEER = PEER_COMMON + r"""
data = np.fromfile(path + "." + str(n), dtype=np.float64)  # positions, then forces: (x, y, z) per particle
src = np.ascontiguousarray(data[:3 * n].reshape(n, 3).T)
f = np.ascontiguousarray(data[3 * n:].reshape(n, 3).T)
t, out = timed(lambda: fmm3dpy.stfmm3d(eps=eps, sources=src, stoklet=f, ifppreg=1))
u = out.pot.reshape(3, n)


def stokeslet_sum(i):
    # Every source but i itself (stfmm3d omits the self pair).
    d = src[:, [i]] - src
    r = np.sqrt((d * d).sum(axis=0))
    r[i] = np.inf
    return (f / r + d * (d * f).sum(axis=0) / r**3).sum(axis=1) / (8 * np.pi)


ref = np.stack([stokeslet_sum(i) for i in idx], axis=1)
print(json.dumps({"fmm3d_s": t, "fmm3d_err_u": rel(u[:, idx], ref)}))
"""


def rpy_points_argv(argv: list[str], path: str) -> list[str]:
    """bench_rpy_fmm writes its points and forces to its 6th argument (+ ".N"); every case gives the 5th
    (the repeats), so the file goes in that place, or replaces the "-" there."""
    return [*argv[:6], path, *argv[7:]]


FMM_PEER = Peer(LFMM3D_PEER, lambda argv, path: [*argv, "--npy", path], ("setup_s", "eval_s"), lambda case: 1, 500)
# As many timed calls as FmmRpy's (bench_rpy_fmm's 5th argument); FmmRpy's setup is set_positions.
RPY_PEER = Peer(STFMM3D_PEER, rpy_points_argv, ("setup_s", "rpy_s"), lambda case: int(case.argv[5]), 200)


GROUPS = [
    Group("fmm", "Laplace FMM against fmm3dpy",
          "One evaluation of potential, gradient and Hessian at the sources (LaplaceFmm, adaptive plane-wave "
          "FMM, docs/theory/fmm.md) against fmm3dpy's `lfmm3d` on the same points and charges; errors: "
          "relative l2 against a direct sum at 500 sampled targets.",
          ["bench_fmm"], fmm_cases, parse_json_lines, "eval_s",
          [("N", "N", "{:.0e}"), ("points", "dist", "{}"), ("eps", "eps", "{}"), ("threads", "threads", "{}"),
           ("setup s", "setup_s", "{:.3f}"), ("eval s", "eval_s", "{:.3f}"), ("err Hess", "err_hess", "{:.1e}"),
           ("fmm3dpy s", "fmm3d_s", "{:.3f}"), ("fmm3dpy err Hess", "fmm3d_err_hess", "{:.1e}"),
           ("fmm3dpy / rpyfmm", "fmm3d_over_rpyfmm", "{:.2f}")],
          keys=("N", "dist", "eps", "threads"), peer=FMM_PEER),
    Group("direct", "Direct kernels",
          "O(N^2) direct sums at N uniform points in the unit cube: Laplace (self pair skipped), RPY "
          "(equal and polydisperse radii) and rpy-rotation (the grand mobility with torques, apply(F, T, U, W)); "
          "pairs per second of wall time.",
          ["bench_direct"], direct_cases, parse_csv, "median_s",
          [("kernel", "kernel", "{}"), ("outputs", "outputs", "{}"), ("N", "n", "{}"), ("threads", "threads", "{}"),
           ("median s", "median_s", "{:.4f}"), ("pairs/s", "pairs_per_s", "{:.3g}")],
          keys=("kernel", "outputs", "n", "threads")),
    Group("rpy", "RPY operators",
          "One product U = M F with FmmRpy (four Laplace FMM densities, docs/theory/rpy.md) on a random "
          "suspension, its error against an exact RPY sum at 200 sampled targets, one Laplace FMM "
          "evaluation on the same points, and the direct operator DirectRpy; then the product with torques "
          "[U; W] = M [F; T] (seven densities plus the rotational near field, docs/theory/rpy.md section 7), "
          "its ratio to the force-only product and its error (the larger of U's and W's). Beside it fmm3dpy's "
          "Stokes FMM `stfmm3d` (velocity of Stokeslets) on the same points and forces at the same eps and thread "
          "count, timed with its setup as FmmRpy's setup s + FmmRpy s, and its relative l2 error against an exact "
          "Stokeslet sum at 200 sampled targets (FMM3D's Stokeslet carries 1/(8 pi), ours 1/(8 pi eta): a constant "
          "factor, which a relative error does not see). `stfmm3d` computes only the Stokeslet part of the RPY "
          "product: one built on FMM3D would add at least a Laplace FMM for the (a^2/3) Laplacian term "
          "(docs/theory/rpy.md Sec. 2), so stfmm3d / FmmRpy is a lower bound of the ratio against such a product.",
          ["bench_rpy_fmm"], rpy_cases, parse_csv, "rpy_s",
          [("points", "dist", "{}"), ("N", "N", "{}"), ("eps", "eps", "{:.0e}"), ("threads", "threads", "{}"),
           ("setup s", "setup_s", "{:.3f}"), ("FmmRpy s", "rpy_s", "{:.3f}"), ("rel err", "rel_l2_err", "{:.1e}"),
           ("stfmm3d s", "fmm3d_s", "{:.3f}"), ("stfmm3d err", "fmm3d_err_u", "{:.1e}"),
           ("stfmm3d / FmmRpy", "fmm3d_over_rpyfmm", "{:.2f}"), ("Laplace FMM s", "laplace1_s", "{:.3f}"),
           ("RPY / Laplace", "ratio_rpy_laplace", "{:.2f}"), ("DirectRpy s", "direct_s", "{:.3f}"),
           ("with torques s", "rot_s", "{:.3f}"), ("torques / forces", "ratio_rot_forces", "{:.2f}"),
           ("rot err", "rot_rel_l2_err", "{:.1e}"), ("leaf cap", "leaf_capacity", "{}")],
          # leaf_option: the requested leaf capacity (0 = automatic); the tree's own capacity
          # (leaf_capacity) may differ between instruction-set levels and commits.
          keys=("dist", "N", "eps", "threads", "leaf_option"), peer=RPY_PEER),
    Group("pse", "PSE on the CPU",
          "The setup of Table I of Fiore, Balboa Usabiaga, Donev & Swan, J. Chem. Phys. 146 (2017) 124116: hard "
          "spheres at "
          "phi = 0.1, xi a = 0.5, tolerance 1e-3, periodic; particle-timesteps per second (PTPS = N / s) of "
          "U = M F and of the split sampler M^{1/2} z (docs/theory/pse.md), each the first after set_positions; "
          "[U; W] = M [F; T] with torques (docs/theory/pse.md section 5) and its ratio to M F.",
          ["bench_pse"], pse_cases, parse_csv, "MF_s",
          [("N", "N", "{}"), ("threads", "threads", "{}"), ("grid", "grid", "{}"), ("M F s", "MF_s", "{:.4f}"),
           ("M F PTPS", "MF_PTPS", "{:.3g}"), ("sample s", "sample_s", "{:.4f}"),
           ("sample PTPS", "sample_PTPS", "{:.3g}"), ("split its", "split_iters", "{}"),
           ("[F; T] s", "MFT_s", "{:.4f}"), ("torques / forces", "torques_over_forces", "{:.2f}")],
          keys=("N", "threads")),
    Group("pse-gpu", "PSE on a GPU",
          "The same setup with the CUDA operator PseRpyCuda: host arrays in and out (transfers count) and device "
          "arrays; one row per variant of its defaults.",
          ["bench_pse"], pse_gpu_cases, parse_csv, "MF_s",
          [("N", "N", "{}"), ("wave", "wave", "{}"), ("lists", "lists", "{}"), ("transfers", "transfers", "{}"),
           ("M F s", "MF_s", "{:.4f}"), ("M F PTPS", "MF_PTPS", "{:.3g}"),
           ("M F PTPS device", "MF_dev_PTPS", "{:.3g}"),
           ("sample PTPS", "sample_PTPS", "{:.3g}")],
          needs_gpu=True, keys=("N", "wave", "lists", "bin", "transfers")),
    Group("bd-gpu", "Brownian dynamics on a GPU",
          "Free-draining BD of 1e6 WCA spheres at phi = 0.15 in a periodic box (Tran et al. (2015), Tables 1-3; "
          "dt 0.01, skin 1.0 a), the whole step on the device engine (docs/gpu-bd.md), per rebuild strategy: the "
          "dynamic test (skin/2), every 10 steps, every step; and the CPU engine on all host cores. ms per step: "
          "the mean over the timed steps, rebuilds included; update: the rest of the step (noise, mobility, "
          "position update, blow-up guard). Target on the GPU: 1.25 ms per step (10x the K20m's 12.5 ms).",
          ["bench_bd"], bd_gpu_cases, parse_csv, "ms_per_step",
          [("engine", "engine", "{}"), ("strategy", "strategy", "{}"), ("N", "N", "{}"), ("threads", "threads", "{}"),
           ("rebuilds", "rebuilds", "{}"), ("ms/step", "ms_per_step", "{:.3f}"),
           ("neighbours ms", "neighbours_ms", "{:.3f}"), ("forces ms", "forces_ms", "{:.3f}"),
           ("update ms", "update_ms", "{:.3f}")],
          needs_gpu=True, keys=("engine", "strategy", "N", "threads")),
    Group("samplers", "Square-root samplers",
          "One Brownian sample M^{1/2} z at tolerance 1e-3 (docs/theory/samplers.md): Lanczos, Chebyshev (spectrum "
          "bounds estimated once, not timed) and both with the block preconditioner (blocks of 48 particles); "
          "random suspension, phi = 0.1; ratio = CPU time of a sample / of one product M F.",
          ["bench_sqrt"], sampler_cases, parse_csv, "sample_wall_s",
          [("operator", "operator", "{}"), ("N", "N", "{}"), ("tol", "tol", "{:.0e}"), ("threads", "threads", "{}"),
           ("method", "method", "{}"), ("iterations", "iterations", "{}"), ("sample s", "sample_wall_s", "{:.3f}"),
           ("sample / product", "ratio_cpu", "{:.1f}")],
          keys=("operator", "N", "tol", "threads", "method")),
    Group("bd", "Brownian dynamics steps",
          "Seconds per step (median after one warm-up step) of a sedimenting cloud at phi = 0.05 (WCA, gravity, "
          "kT 1, dt 0.01, docs/theory/bd.md) with direct, FMM or PSE (periodic) hydrodynamics, tolerance 1e-3.",
          ["bench_bd"], bd_cases, parse_csv, "sec_per_step",
          [("method", "method", "{}"), ("N", "N", "{}"), ("threads", "threads", "{}"),
           ("s / step", "sec_per_step", "{:.4f}"), ("sampler its", "lanczos_its", "{:.1f}"),
           ("drift s", "drift", "{:.3g}"),
           ("sqrt s", "sqrt", "{:.3g}")],
          keys=("method", "N", "threads")),
    Group("bd-open", "Free-space BD with HI at scale",
          "Seconds per step (median of 3 after one warm-up step) of the sedimenting cloud of group bd (phi = 0.05, "
          "WCA, gravity, tolerance 1e-3) in free space: pse-open = PSE with open boundaries (docs/theory/pse.md "
          "section 6: one fused pass, split sampler) against fmm = FmmRpy with the block-preconditioned Lanczos "
          "sampler (method fmm), and direct = exact sums with the same sampler (the crossover); "
          "products = mobility products per step.",
          ["bench_bd"], bd_open_cases, parse_csv, "sec_per_step",
          [("method", "method", "{}"), ("N", "N", "{}"), ("threads", "threads", "{}"),
           ("s / step", "sec_per_step", "{:.4f}"), ("products", "products", "{:.1f}"),
           ("drift s", "drift", "{:.3g}"), ("sqrt s", "sqrt", "{:.3g}"), ("plan s", "plan", "{:.3g}")],
          keys=("method", "N", "threads")),
    Group("sac", "Alumina and silica: Table 4 of Tran et al. (2015) on the CPU",
          "The three systems of Table 4 of Tran, Crespin, Cerbelaud & Videcoq (Eurographics "
          "2015, Sec. 4.3): alumina (a = 200 nm, Langevin) with silica (a = 12.5 nm, Brownian), dt = 5e-10 s, "
          "free draining, the SAC scheme (docs/theory/bd.md Sec. 9) and the naive one, through the same "
          "Integrator as `rpyfmm bd`. Potentials and units of examples/bd/alumina_silica (a 36-18 well and WCA "
          "stand in for the alumina-silica and silica-silica DLVO pairs, which diverge at contact); periodic "
          "cube at alumina volume fraction 0.03 (the paper's Annex 2), random non-overlapping start; ms per "
          "iteration = mean over the timed steps after 3 warm-up steps. `K20m ms` is the paper's figure for its "
          "GPU code on a Tesla K20m, copied from Table 4, not measured here; ours are CPU figures on this "
          "machine, comparable side by side only with each other. Each pair of types is listed within its own "
          "cut-off plus the skin of the largest (alumina-alumina DLVO, 500 nm, + 30 %; docs/theory/bd.md "
          "Sec. 4), as the paper keeps one list per pair kind (its Sec. 4.2): a silica lists ~4 neighbours.",
          ["bench_bd"], sac_cases, parse_csv, "ms_per_iteration",
          [("system", "system", "{}"), ("alumina", "alumina", "{}"), ("silica", "silica", "{}"),
           ("scheme", "scheme", "{}"), ("threads", "threads", "{}"), ("ms / iteration", "ms_per_iteration", "{:.3g}"),
           ("K20m ms (paper)", "k20m_ms", "{:.2f}"), ("neighbours ms", "neighbours_ms", "{:.3g}"),
           ("forces ms", "forces_ms", "{:.3g}"), ("other ms", "other_ms", "{:.3g}"),
           ("list entries / particle", "list_entries_per_particle", "{:.1f}"), ("adsorbed", "adsorbed", "{}")],
          keys=("system", "scheme", "threads")),
    Group("rigid", "Rigid bodies",
          "Bead-shell spheres at body volume fraction 0.1 (docs/theory/rigid.md): one mobility solve (GMRES with "
          "the body preconditioner, tolerance 1e-6) with direct or FMM bead operators, and one Brownian step "
          "with the FMM operator (with and without the RFD drift).",
          ["bench_rigid", "bench_rigid_dynamics"], rigid_cases, parse_csv, "time_s",
          [("benchmark", "benchmark", "{}"), ("operator", "operator", "{}"), ("bodies", "bodies", "{}"),
           ("beads", "beads", "{}"), ("threads", "threads", "{}"), ("drift", "drift", "{}"),
           ("GMRES its", "iterations", "{}"), ("s", "time_s", "{:.4f}"), ("setup s", "setup_s", "{:.4f}")],
          keys=("benchmark", "operator", "bodies", "beads", "threads", "drift")),
    Group("mpi", "Laplace FMM, direct RPY and free-draining BD across MPI ranks",
          "DistributedLaplaceFmm (fmm, docs/mpi.md), DistributedDirectRpy (direct, one product U = M F) and "
          "DistributedBd (bd: WCA spheres of radius 0.5 at volume fraction 0.15 in a periodic box, dt 1e-3, "
          "eval s = seconds per step over 20 steps, comm s = the halo's positions per step, essential = the largest "
          "part of a rank, own + halo particles, serial s = bd::Integrator per step on one rank) on P "
          "ranks of one OpenMP thread each, uniform sources in the unit cube; fmm: eps 1e-6, one density, potential "
          "and gradient: strong scaling at fixed N and weak scaling at fixed N / P. plan s = set_points or "
          "set_positions; eval s = median of 3 evaluations or products (the slowest rank's); comm s = the slowest "
          "rank's time in the exchanges of one; MB = bytes received by all ranks in one; essential = the largest "
          "serial-FMM source set of a rank (own + halo + equivalent nodes). On the 2-core development machine 3 and "
          "4 ranks oversubscribe the cores: their times show the work per rank and the volume, not a speed-up. "
          "overlap s = fmm with the serial FMM split to run during the exchanges (overlap_exchange), timed "
          "alternately with eval s in the same run.",
          ["bench_mpi_fmm", "bench_mpi_direct", "bench_mpi_bd"], mpi_cases, parse_json_lines, "eval_s",
          [("method", "method", "{}"), ("scaling", "scaling", "{}"), ("ranks", "ranks", "{}"), ("N", "N", "{:.2g}"),
           ("plan s", "plan_s", "{:.3f}"), ("eval s", "eval_s", "{:.3f}"), ("overlap s", "eval_overlap_s", "{:.3f}"),
           ("serial FMM s", "eval_work_fmm_s", "{:.3f}"),
           ("comm s", "eval_comm_s", "{:.4f}"), ("plan MB", "plan_MB", "{:.2f}"), ("eval MB", "eval_MB", "{:.2f}"),
           ("essential", "essential_max", "{:.0f}"), ("serial s", "serial_s", "{:.4f}")],
          keys=("method", "scaling", "ranks", "N")),
    Group("mpi-block", "Several right-hand sides per product across MPI ranks",
          "apply_block with nrhs = 4 right-hand sides against 4 calls of apply on the same operator and shares "
          "(docs/mpi.md, \"Several right-hand sides\"): DistributedDirectRpy (one pass of the source blocks for "
          "every right-hand side) and DistributedFmmRpy at eps 1e-6 (one distributed Laplace evaluation carrying "
          "the densities of every right-hand side), N spheres of radius 0.001 uniform in the unit cube, P ranks of "
          "one OpenMP thread each. block s and 4 x apply s = medians of 3 (the slowest rank's); serial FMM s = the "
          "owners' serial Laplace FMM inside one apply_block and one apply (fmm only).",
          ["bench_mpi_block"], mpi_block_cases, parse_json_lines, "block_s",
          [("method", "method", "{}"), ("ranks", "ranks", "{}"), ("N", "N", "{:.2g}"), ("nrhs", "nrhs", "{}"),
           ("block s", "block_s", "{:.3f}"), ("4 x apply s", "singles_s", "{:.3f}"),
           ("speed-up", "speedup", "{:.2f}"), ("serial FMM s, block", "block_fmm_s", "{:.3f}"),
           ("serial FMM s, apply", "single_fmm_s", "{:.3f}")],
          keys=("method", "ranks", "N", "nrhs")),
    Group("mpi-fmm-rpy", "Distributed FmmRpy beside the serial FmmRpy",
          "One product U = M F of DistributedFmmRpy (docs/mpi.md, \"Distributed FmmRpy\") at eps 1e-6 on P ranks of "
          "one OpenMP thread each, N spheres of radius 1 uniform in a cube at volume fraction 0.1, automatic leaves. "
          "eval s = median of 3 products after a first (the slowest rank's); far s = the owners' serial Laplace FMM, "
          "near s = the near field's RPY blocks, other s = the rest of the product's local work, comm s = the "
          "exchanges (near comm s: the near field's velocities back), each the slowest rank's in the last product; "
          "halo = the largest halo of a rank; serial s = rpy::FmmRpy::apply on the whole set on rank 0 with the "
          "other ranks asleep (median of 3 after a first), serial near s its near field; err = relative l2 "
          "difference of U from the serial FmmRpy's (each within eps of the exact product).",
          ["bench_mpi_fmm_rpy"], mpi_fmm_rpy_cases, parse_json_lines, "eval_s",
          [("ranks", "ranks", "{}"), ("N", "N", "{:.2g}"), ("plan s", "plan_s", "{:.3f}"),
           ("eval s", "eval_s", "{:.3f}"), ("far s", "far_s", "{:.3f}"), ("near s", "near_s", "{:.3f}"),
           ("other s", "other_s", "{:.3f}"), ("comm s", "comm_s", "{:.3f}"), ("near comm s", "near_comm_s", "{:.4f}"),
           ("halo", "halo_max", "{:.0f}"), ("serial s", "serial_s", "{:.3f}"),
           ("serial near s", "serial_near_s", "{:.3f}"), ("err", "err_vs_serial", "{:.1e}")],
          keys=("ranks", "N")),
    Group("mpi-curve", "The distributed Laplace FMM along the Morton and the Hilbert curve",
          "DistributedLaplaceFmm (docs/mpi.md, \"Space-filling-curve partition\") with the sources partitioned "
          "along each curve (SfcCurve), one density, potential and gradient, P ranks of one OpenMP thread each, N "
          "sources in the unit cube, uniform or clustered (half of them in 8 cubes of side 0.02). essential = the "
          "largest serial-FMM source set of a rank (own + halo + equivalent nodes); halo max = the largest halo "
          "of a rank; eval s = median of 3 evaluations (the slowest rank's), the two curves alternating. The "
          "counts are exact; on the 2-core development machine 3 and 4 ranks oversubscribe the cores.",
          ["bench_mpi_curve"], mpi_curve_cases, parse_json_lines, "eval_s",
          [("points", "points", "{}"), ("eps", "eps", "{:g}"), ("ranks", "ranks", "{}"), ("N", "N", "{:.2g}"),
           ("curve", "curve", "{}"), ("essential", "essential_max", "{:.0f}"), ("halo max", "halo_max", "{:.0f}"),
           ("nodes", "nodes", "{:.0f}"), ("plan s", "plan_s", "{:.3f}"), ("eval s", "eval_s", "{:.3f}")],
          keys=("points", "eps", "ranks", "N", "curve")),
    Group("mpi-block-cache", "The block preconditioner's blocks kept between samples across ranks",
          "mpi::sqrt_apply with the block preconditioner (Lanczos, tolerance 1e-3, automatic block size; docs/mpi.md, "
          "\"Brownian displacements\") on DistributedDirectRpy or DistributedFmmRpy (eps 1e-6), N spheres of "
          "radius 0.001 uniform in the unit cube, 2 ranks of one OpenMP thread each: first s = the first call after "
          "set_positions (gather, bisection and factors of the blocks, then the sample), second s = a second call "
          "on the same positions (the kept blocks); build s and gather s = the first call's, exchange s = the "
          "second call's exchanges of the blocks; medians of 3 (the slowest rank's).",
          ["bench_mpi_block_cache"], mpi_block_cache_cases, parse_json_lines, "second_s",
          [("method", "method", "{}"), ("ranks", "ranks", "{}"), ("N", "N", "{:.2g}"),
           ("first s", "first_s", "{:.3f}"), ("second s", "second_s", "{:.3f}"), ("build s", "build_s", "{:.4f}"),
           ("gather s", "gather_s", "{:.4f}"), ("exchange s", "exchange_s", "{:.4f}"),
           ("iterations", "iterations", "{}")],
          keys=("method", "ranks", "N")),
    Group("mpi-partition", "SfcPartition's cuts: multi-way search against bisection",
          "One SfcPartition construction (docs/mpi.md, \"Space-filling-curve partition\") of N uniform particles "
          "with unit weights on P ranks of one OpenMP thread each, its cuts found by the multi-way search (up to 256 "
          "ways per round within 2^16 sums per MPI_Allreduce) or by bisection (one sum per cut and round); "
          "construct s = median over reps of one construction (the slowest rank's), allreduce s = the same number of "
          "MPI_Allreduce calls of the first round's size replayed alone; same = both searches gave the same "
          "splitters. On the 2-core development machine 4 ranks oversubscribe the cores.",
          ["bench_mpi_partition"], mpi_partition_cases, parse_json_lines, "construct_s",
          [("ranks", "ranks", "{}"), ("N", "N", "{:.2g}"), ("search", "search", "{}"), ("ways", "ways", "{}"),
           ("rounds", "rounds", "{}"), ("construct s", "construct_s", "{:.4f}"), ("allreduce s", "allreduce_s", "{:.2e}"),
           ("same", "same_splitters", "{}")],
          keys=("ranks", "N", "search")),
    Group("mpi-bisection", "The block preconditioner's blocks across ranks: distributed bisection against gather",
          "The blocks of the block preconditioner (blocks of 32, docs/mpi.md, \"Brownian displacements\") of N "
          "uniform particles on P ranks of one OpenMP thread each, built by the distributed median bisection (what "
          "the samplers run) or by gathering the whole set to every rank and bisecting there (the baseline); "
          "order slabs: each rank's share a slab of the cube, as a spatial partition gives; random: every rank's "
          "share spread over the cube. s = median over reps of one build (the slowest rank's); bytes max = the most "
          "bytes a rank received in one build; same = both gave the same blocks and owners. On the 2-core "
          "development machine 4 ranks oversubscribe the cores.",
          ["bench_mpi_bisection"], mpi_bisection_cases, parse_json_lines, "distributed_seconds",
          [("order", "order", "{}"), ("ranks", "ranks", "{}"), ("N", "n", "{:.2g}"), ("levels", "levels", "{}"),
           ("rounds", "rounds", "{}"), ("gather s", "gathered_seconds", "{:.4f}"),
           ("gather bytes max", "gathered_bytes_max", "{:.2e}"), ("distributed s", "distributed_seconds", "{:.4f}"),
           ("distributed bytes max", "distributed_bytes_max", "{:.2e}"), ("same", "same", "{}")],
          keys=("order", "ranks", "n")),
    Group("mpi-targets", "The distributed Laplace FMM's separate targets: own cuts or the sources' cuts",
          "DistributedLaplaceFmm (docs/mpi.md, \"Targets partitioned by the sources' cuts\") with N uniform sources "
          "and N targets (uniform, or 90 % of them in the cube [0.6, 0.7]^3: clustered), eps 1e-6, one density, "
          "potential and gradient, P ranks of one OpenMP thread each; follow = targets_follow_sources (1: the "
          "targets partitioned by the sources' cuts, 0: by their own balanced cuts); targets max = the most "
          "targets a rank owns; essential = the largest serial-FMM source set of a rank; eval s = median of 3 "
          "evaluations (the slowest rank's), the two partitions alternating. On the 2-core development machine 4 "
          "ranks oversubscribe the cores.",
          ["bench_mpi_targets"], mpi_targets_cases, parse_json_lines, "eval_s",
          [("points", "points", "{}"), ("ranks", "ranks", "{}"), ("N", "N", "{:.2g}"),
           ("follow", "targets_follow_sources", "{}"), ("targets max", "owned_targets_max", "{:.0f}"),
           ("halo max", "halo_max", "{:.0f}"), ("essential", "essential_max", "{:.0f}"), ("plan s", "plan_s", "{:.3f}"),
           ("eval s", "eval_s", "{:.3f}"), ("exchange s", "eval_comm_essential_s", "{:.4f}"),
           ("serial FMM s", "eval_work_fmm_s", "{:.3f}")],
          keys=("points", "ranks", "N", "targets_follow_sources")),
]
GROUP_BY_NAME = {g.name: g for g in GROUPS}
TIME_COLUMNS = {"solve": "solve_s", "step": "step_s"}  # rigid: the time column of each program


# ----------------------------------------------------------------------------------------------
# Machine, commit, builds


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    import platform

    return platform.processor() or platform.machine()


def git(*args: str, cwd: Path = ROOT) -> str:
    return subprocess.run(["git", *args], cwd=cwd, capture_output=True, text=True, check=True).stdout.strip()


def commit_of(tree: Path) -> str:
    """The commit of the tree (+dirty where the programs' sources changed); RPYFMM_BENCH_COMMIT where the
    tree is a copy without git (a machine the programs were carried to)."""
    if os.environ.get("RPYFMM_BENCH_COMMIT"):
        return os.environ["RPYFMM_BENCH_COMMIT"]
    try:
        sha = git("rev-parse", "--short=12", "HEAD", cwd=tree)
        # The driver and its outputs do not change the programs measured.
        outside_results = ["--", ".", ":!bench/README.md", ":!bench/results", ":!bench/run.py"]
        changed = git("status", "--porcelain", "--untracked-files=no", *outside_results, cwd=tree)
        return sha + ("+dirty" if changed else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def simd_level(build: Path, simd: str | None) -> str:
    """The instruction-set level the library runs at, as the CLI reports it ("simd" of --json)."""
    cli = build / "apps" / "rpyfmm"
    with tempfile.TemporaryDirectory() as tmp:
        src, q, out = (str(Path(tmp) / name) for name in ("x.txt", "q.txt", "u.npy"))
        Path(src).write_text("0 0 0\n1 0 0\n")
        Path(q).write_text("1\n1\n")
        try:
            text = subprocess.run([str(cli), "laplace", "--sources", src, "--charges", q, "--direct", "--out", out,
                                   "--json"], env=run_env(1, simd), capture_output=True, text=True, check=True).stdout
            return json.loads(text.splitlines()[-1]).get("simd", "unknown")
        except (OSError, subprocess.CalledProcessError, ValueError, IndexError):
            return "unknown"


def machine(build: Path) -> dict:
    return {"cpu": cpu_model(), "isa": simd_level(build, None), "cores": CORES,
            "load_average": [round(x, 2) for x in os.getloadavg()]}


def has_gpu() -> bool:
    try:
        return subprocess.run(["nvidia-smi", "-L"], capture_output=True, check=True).stdout.strip() != b""
    except (OSError, subprocess.CalledProcessError):
        return False


def cache_value(build: Path, name: str, fallback: str) -> str:
    cache = build / "CMakeCache.txt"
    if cache.exists():
        for line in cache.read_text().splitlines():
            if line.startswith(name + ":"):
                return line.split("=", 1)[1]
    return fallback


def configure(source: Path, build: Path, like: Path | None) -> None:
    """The release preset without tests and Python; CUDA as the preset finds it, or as in the build `like`."""
    cuda = [f"-DRPYFMM_USE_CUDA={cache_value(like, 'RPYFMM_USE_CUDA', 'OFF')}"] if like else []
    cmd = ["cmake", "--preset", "release", "-B", str(build), "-DRPYFMM_BUILD_TESTS=OFF", "-DRPYFMM_BUILD_PYTHON=OFF",
           *cuda]
    print("#", " ".join(cmd), file=sys.stderr)
    subprocess.run(cmd, cwd=source, check=True, stdout=subprocess.DEVNULL)


def available_targets(build: Path) -> set[str]:
    """The targets of a build: Makefiles list them as "... NAME", Ninja as "NAME: RULE"."""
    out = subprocess.run(["cmake", "--build", str(build), "--target", "help"], capture_output=True, text=True).stdout
    lines = out.splitlines()
    return {line.split()[1] for line in lines if line.startswith("... ")} | {
        line.split(":")[0].strip() for line in lines if not line.startswith("...") and ":" in line}


def build_targets(source: Path, build: Path, targets: list[str], like: Path | None = None) -> None:
    """The benchmark programs, and for the main build the CLI (which reports the instruction-set level)."""
    if not (build / "CMakeCache.txt").exists():
        configure(source, build, like)
    present = available_targets(build)
    wanted = [t for t in [*([] if like else ["rpyfmm_cli"]), *targets] if t in present]
    cmd = ["nice", "-n", "5", "cmake", "--build", str(build), "-j", str(CORES), "--target", *wanted]
    print("#", " ".join(cmd), file=sys.stderr)
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)


def compare_tree(commit: str) -> Path:
    """A detached worktree of COMMIT under build/, built with the same preset as the main build."""
    sha = git("rev-parse", "--short=12", commit)
    tree = ROOT / "build" / f"compare-{sha}"
    if not (tree / ".git").exists():
        git("worktree", "add", "--detach", str(tree), sha)
    return tree


# ----------------------------------------------------------------------------------------------
# Running


def run_env(threads: int, simd: str | None) -> dict:
    env = dict(os.environ, OMP_NUM_THREADS=str(threads))
    env.pop("RPYFMM_SIMD", None)
    if simd:
        env["RPYFMM_SIMD"] = simd
    return env


def fmm3d_python() -> str | None:
    """An interpreter that imports fmm3dpy (the benchmark venv first), or None."""
    for python in (str(VENV_PYTHON), sys.executable):
        if Path(python).exists() and subprocess.run([python, "-c", "import fmm3dpy"],
                                                    capture_output=True).returncode == 0:
            return python
    return None


def fmm3d_version(python: str | None) -> str:
    if python is None:
        return ""
    code = "import importlib.metadata as m; print(m.version('fmm3dpy'))"
    return subprocess.run([python, "-c", code], capture_output=True, text=True).stdout.strip()


def run_peer(peer: Peer, python: str, case: Case, points: str, rows: list[dict]) -> dict[tuple, dict]:
    """The peer's columns for each (N, eps) of the rows, on the points the program wrote, at the case's
    thread count."""
    columns = {}
    for n, eps in dict.fromkeys((row["N"], row["eps"]) for row in rows):
        argv = [python, "-c", peer.script, points, str(n), str(eps), str(peer.samples), str(peer.reps(case))]
        out = subprocess.run(argv, env=run_env(case.threads, None), capture_output=True, text=True, check=True)
        columns[n, eps] = json.loads(out.stdout.splitlines()[-1])
    return columns


def run_case(group: Group, case: Case, variant: Variant, peer_python: str | None, cpu: int | None = None) -> list[dict]:
    """One run of a case on a variant (pinned to logical CPU `cpu` where given), and of the group's peer
    where `peer_python` (an interpreter that imports fmm3dpy) is given; its rows."""
    program = variant.build / "bench" / case.argv[0]
    if not program.exists():
        return []
    with_peer = bool(case.peer and peer_python and group.peer)
    with tempfile.TemporaryDirectory() as tmp:
        points = str(Path(tmp) / "points")  # the program's file (or files) of points for the peer
        argv = group.peer.points_argv(case.argv, points) if with_peer else case.argv
        pin = (lambda: os.sched_setaffinity(0, {cpu})) if cpu is not None else None
        out = subprocess.run([str(program), *argv[1:]], env=run_env(case.threads, variant.simd), capture_output=True,
                             text=True, check=True, preexec_fn=pin).stdout
        rows = [r for r in group.parse(out) if all(r.get(k) == v for k, v in case.keep.items())]
        for row in rows:
            row.update(case.key, threads=row.get("threads", case.threads))
        extra = run_peer(group.peer, peer_python, case, points, rows) if with_peer else {}
    for row in rows:
        row.update(extra.get((row.get("N"), row.get("eps")), {}))
        derive(group, row)
    return rows


def derive(group: Group, row: dict) -> None:
    """Columns computed from others: fmm3dpy's time over ours (both with their setup), rigid's time and GMRES
    columns."""
    if group.peer and "fmm3d_s" in row:
        row["fmm3d_over_rpyfmm"] = row["fmm3d_s"] / sum(row[c] for c in group.peer.ours)
    if group.name == "rigid":
        row["time_s"] = row[TIME_COLUMNS[row["benchmark"]]]
        row.setdefault("drift", "")
        row.setdefault("iterations", row.get("solve_iterations"))


def row_key(group: Group, row: dict) -> tuple:
    return tuple(str(row.get(c, "")) for c in group.keys)


def median_rows(group: Group, runs: list[dict]) -> list[dict]:
    """Per case key: the median of every numeric column over the rounds (other columns: the last run's)."""
    by_key: dict[tuple, list[dict]] = {}
    for row in runs:
        by_key.setdefault(row_key(group, row), []).append(row)
    merged = []
    for rows in by_key.values():
        out = dict(rows[-1])
        for k, v in out.items():
            values = [r[k] for r in rows if isinstance(r.get(k), (int, float))]
            if isinstance(v, (int, float)) and len(values) == len(rows):
                out[k] = statistics.median(values)
        merged.append(out)
    return merged


def one_cpu_per_core() -> list[int]:
    """One logical CPU of each physical core this process may run on (the first of its siblings)."""
    cpus = []
    for cpu in sorted(os.sched_getaffinity(0)):
        try:
            siblings = Path(f"/sys/devices/system/cpu/cpu{cpu}/topology/thread_siblings_list").read_text()
            first = int(siblings.replace("-", ",").split(",")[0])
        except (OSError, ValueError):
            first = cpu
        if first == cpu:
            cpus.append(cpu)
    return cpus


def run_group_concurrently(group: Group, variants: list[Variant], mode: str, rounds: int) -> dict[str, list[dict]]:
    """--concurrent: for each case, its rounds on every variant at once, one-thread runs pinned to one
    physical core each (so the variants share the machine's memory system alike); medians per variant."""
    from concurrent.futures import ThreadPoolExecutor

    cpus = one_cpu_per_core()
    runs: dict[str, list[dict]] = {v.name: [] for v in variants}
    for case in group.cases(mode):
        jobs = [(r, v) for r in range(rounds) for v in variants]
        if case.threads != 1 or len(jobs) > len(cpus):
            raise SystemExit(f"--concurrent needs one-thread cases and {len(jobs)} physical cores ({len(cpus)} here)")
        start = datetime.datetime.now()
        with ThreadPoolExecutor(len(jobs)) as pool:
            futures = [(v, pool.submit(run_case, group, case, v, None, cpus[i])) for i, (r, v) in enumerate(jobs)]
            for v, future in futures:
                runs[v.name] += future.result()
        seconds = (datetime.datetime.now() - start).total_seconds()
        print(f"# {group.name}: {len(jobs)} runs at once of {' '.join(case.argv)}: {seconds:.1f} s", file=sys.stderr,
              flush=True)
    return {name: median_rows(group, rows) for name, rows in runs.items()}


def run_group(group: Group, variants: list[Variant], mode: str, rounds: int) -> dict[str, list[dict]]:
    """Every case on every variant in turn, `rounds` times; medians per variant (the peer code: headline runs)."""
    peer_python = fmm3d_python() if group.peer and len(variants) == 1 else None
    runs: dict[str, list[dict]] = {v.name: [] for v in variants}
    for r in range(rounds):
        for case in group.cases(mode):
            for i, variant in enumerate(variants):
                start = datetime.datetime.now()
                runs[variant.name] += run_case(group, case, variant, peer_python if i == 0 else None)
                seconds = (datetime.datetime.now() - start).total_seconds()
                print(f"# {group.name} round {r + 1}/{rounds} {variant.name}: {' '.join(case.argv)} "
                      f"(threads {case.threads}): {seconds:.1f} s", file=sys.stderr, flush=True)
    return {name: median_rows(group, rows) for name, rows in runs.items()}


# ----------------------------------------------------------------------------------------------
# Results files


def record(group: Group, args, variants: list[Variant], rows: dict[str, list[dict]]) -> dict:
    return {
        "group": group.name,
        "generated_by": "python3 bench/run.py " + " ".join(sys.argv[1:]),
        "mode": size_mode(args),
        "concurrent": bool(args.concurrent),
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "machine": machine(variants[0].build),
        "rounds": args.rounds,
        "variants": [{"name": v.name, "commit": commit_of(v.build.parent.parent),
                      "simd": simd_level(v.build, v.simd)} for v in variants],
        "fmm3dpy": fmm3d_version(fmm3d_python()) if group.peer and len(variants) == 1 else "",
        "note": args.note or "",
        "rows": rows,
    }


def results_name(group: Group, variants: list[Variant], args) -> str:
    if args.compare:
        return f"{group.name}.compare-{variants[1].build.parent.parent.name.removeprefix('compare-')}.json"
    return f"{group.name}.simd-levels.json" if args.simd_levels else f"{group.name}.json"


def load_results() -> dict[str, dict]:
    return {p.name: json.loads(p.read_text()) for p in sorted(RESULTS.glob("*.json"))}


# ----------------------------------------------------------------------------------------------
# The page


def cell(fmt: str, value) -> str:
    if value is None or value == "":
        return ""
    try:
        return fmt.format(value)
    except (ValueError, TypeError):
        return str(value)


def markdown_table(headers: list[str], lines: list[list[str]]) -> list[str]:
    return ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)] + [
        "| " + " | ".join(line) + " |" for line in lines]


def provenance(rec: dict) -> str:
    m, v = rec["machine"], rec["variants"][0]
    return (f"{m['cpu']} ({v['simd']}, {m['cores']} cores, load average {m['load_average'][0]} at the start), "
            f"commit {v['commit']}, {rec['date']}, `--{rec['mode']}`, median of {rec['rounds']} run(s) of each "
            f"program's own median")


def headline_section(group: Group, rec: dict | None) -> list[str]:
    lines = [f"## {group.title}", "", group.about, ""]
    if rec is None:
        where = "on a machine with a GPU and a build with `-DRPYFMM_USE_CUDA=ON`" if group.needs_gpu else "here"
        return lines + [f"Not measured on this machine: run `python3 bench/run.py --only {group.name}` {where}.", ""]
    rows = rec["rows"][rec["variants"][0]["name"]]
    columns = [c for c in group.columns if any(c[1] in r for r in rows)]
    table = [[cell(fmt, r.get(col)) for _, col, fmt in columns] for r in rows]
    lines += [provenance(rec) + ".", ""] + markdown_table([h for h, _, _ in columns], table) + [""]
    if group.peer and "fmm3dpy" in rec:  # records from before the group had a peer say nothing of it
        lines += [f"fmm3dpy {rec['fmm3dpy']} (the PyPI wheel, in `build/bench-venv`), same thread count; the ratio "
                  "divides its time by ours with the setup included." if rec.get("fmm3dpy") else
                  "fmm3dpy did not import here: no peer columns (`pip install fmm3dpy` into `build/bench-venv`).", ""]
    if (RESULTS / f"{group.name}.png").exists():
        lines += [f"![{group.title}](results/{group.name}.png)", ""]
    return lines


def ratio_section(group: Group, rec: dict, what: str) -> list[str]:
    names = [v["name"] for v in rec["variants"]]
    base = {row_key(group, r): r for r in rec["rows"][names[0]]}
    keys = [(h, c) for h, c, _ in group.columns if c in group.keys]
    headers = [h for h, _ in keys] + [f"{n} s" for n in names] + [f"{names[0]} / {n}" for n in names[1:]]
    table = []
    for key, row in base.items():
        others = {n: {row_key(group, r): r for r in rec["rows"][n]}.get(key, {}) for n in names}
        times = [others[n].get(group.time_key) for n in names]
        table.append([str(row.get(c, "")) for _, c in keys] + [cell("{:.4g}", t) for t in times] + [
            cell("{:.2f}", times[0] / t) if t and times[0] else "" for t in times[1:]])
    variants = ", ".join(f"{v['name']} = {v['commit']}" + (f" at {v['simd']}" if v["simd"] != "unknown" else "")
                         for v in rec["variants"])
    note = [rec["note"], ""] if rec.get("note") else []
    about = (f"{provenance(rec)}; {variants}; column `{group.time_key}`, lower is better (a ratio below 1: "
             f"{names[0]} faster), the variants run alternately.")
    return [f"### Group `{group.name}`: {what}", "", *note, about, ""] + markdown_table(headers, table) + [""]


INTRO = """# Benchmarks

<!-- Generated by bench/run.py from bench/results/*.json; edit bench/run.py, not this page. -->
Generated by `bench/run.py` from the JSON files in `bench/results/` (machine, commit, date and
every measured row). Regenerate everything with one command (about 18 minutes on 2 cores with the
fmm3dpy peer, 12 without; `--full` for the larger sizes):

    python3 bench/run.py --quick

`--only GROUP ...` runs some groups, `--compare COMMIT` runs every case on this tree and on COMMIT
(built in `build/compare-<sha>`) in turn and shows the ratios, `--simd-levels` runs them at every
instruction-set level of the CPU (`RPYFMM_SIMD`; with `--isa-rows` at the sizes that
docs/reproducibility.md quotes, and with `--concurrent` each case's rounds on all levels at once, one
physical core each), `--render-only` redraws this page. Times are medians; 1-thread rows are the per-core figures, the rows at all cores show the parallel speed-up.
Where the machine was shared (load average above its cores), 1-thread figures are the steadier
and rows at all cores mostly show the contention. The fmm3dpy peer comes from PyPI:

    python3 -m venv --system-site-packages build/bench-venv && build/bench-venv/bin/pip install fmm3dpy matplotlib
"""


def render(results: dict[str, dict]) -> str:
    lines = [INTRO]
    for group in GROUPS:
        lines += headline_section(group, results.get(f"{group.name}.json"))
    if any(".compare-" in name or name.endswith(".simd-levels.json") for name in results):
        lines += ["## Side by side", "", "Runs of `--compare COMMIT` and `--simd-levels`: each case on both "
                  "builds (or levels) in turn, in the same run.", ""]
    for name, rec in results.items():
        group = GROUP_BY_NAME.get(rec["group"])
        if group and ".compare-" in name:
            lines += ratio_section(group, rec, f"this tree against {rec['variants'][1]['commit']}")
        elif group and name.endswith(".simd-levels.json"):
            lines += ratio_section(group, rec, "instruction-set levels")
    return "\n".join(lines).rstrip() + "\n"


def plot(group: Group, rec: dict) -> None:
    """A bar chart of the group's time column (log scale), one bar per headline row, where matplotlib imports."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return
    rows = rec["rows"][rec["variants"][0]["name"]]
    labels = [" ".join(row_key(group, r)) for r in rows]
    fig, ax = plt.subplots(figsize=(8, 0.3 * len(rows) + 1.2))
    ax.barh(labels, [r.get(group.time_key, 0) for r in rows], label="rpyfmm")
    if group.peer and rec.get("fmm3dpy"):
        ax.barh(labels, [r.get("fmm3d_s", 0) for r in rows], height=0.4, label="fmm3dpy")
        ax.legend()
    ax.set_xscale("log")
    unit = "milliseconds" if group.time_key.endswith(("_ms", "ms_per_iteration")) else "seconds"
    ax.set_xlabel(f"{group.time_key} ({unit}, median)")
    ax.set_title(f"{group.title}: {rec['machine']['cpu']}, {rec['variants'][0]['commit']}", fontsize=9)
    ax.tick_params(axis="y", labelsize=7)
    fig.tight_layout()
    fig.savefig(RESULTS / f"{group.name}.png", dpi=90)
    plt.close(fig)


# ----------------------------------------------------------------------------------------------
# Driver


def parse_args() -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    size = ap.add_mutually_exclusive_group()
    size.add_argument("--quick", action="store_true", help="small sizes, about 18 minutes on 2 cores (default)")
    size.add_argument("--full", action="store_true", help="the sizes of the headline tables on a quiet machine")
    size.add_argument("--isa-rows", action="store_true",
                      help="with --simd-levels: the rows of docs/reproducibility.md (Laplace FMM and FmmRpy at 1e6 "
                           "and 1e-6, the direct kernels at 1e4, PSE at 1e5; one thread)")
    ap.add_argument("--only", nargs="+", choices=[g.name for g in GROUPS], help="run these groups only")
    ap.add_argument("--compare", metavar="COMMIT", help="also build COMMIT and report new/old ratios")
    ap.add_argument("--simd-levels", action="store_true", help="run at every instruction-set level of the CPU")
    ap.add_argument("--build", default="build/release", help="build directory (configured if missing)")
    ap.add_argument("--rounds", type=int, help="runs of each case (default 1 quick, 3 full or side by side)")
    ap.add_argument("--no-build", action="store_true", help="use the programs as built")
    ap.add_argument("--levels", nargs="+", choices=["avx512", "avx2", "scalar"],
                    help="with --simd-levels: these levels only (where the CPU has them)")
    ap.add_argument("--concurrent", action="store_true",
                    help="run each case's rounds on every variant at once, one physical core each (one-thread cases)")
    ap.add_argument("--render-only", action="store_true", help="only redraw bench/README.md from the JSON files")
    ap.add_argument("--note", help="a sentence shown with this run's tables (e.g. what --compare compares)")
    args = ap.parse_args()
    if args.rounds is None:
        args.rounds = 3 if args.full or args.compare or args.simd_levels else 1
    if (args.isa_rows or args.levels) and not args.simd_levels:
        ap.error("--isa-rows and --levels go with --simd-levels")
    return args


def size_mode(args) -> str:
    return "isa" if args.isa_rows else "full" if args.full else "quick"


def selected_groups(args) -> list[Group]:
    groups = [g for g in GROUPS if not args.only or g.name in args.only]
    gpu = has_gpu()
    skipped = [g.name for g in groups if g.needs_gpu and not gpu]
    if skipped:
        print(f"# no GPU: skipping {', '.join(skipped)}", file=sys.stderr)
    return [g for g in groups if gpu or not g.needs_gpu]


def make_variants(args, build: Path) -> list[Variant]:
    if args.compare:
        tree = compare_tree(args.compare)
        return [Variant("new", build), Variant("old", tree / "build" / "release")]
    if args.simd_levels:
        levels = []
        for level in args.levels or ("avx512", "avx2", "scalar"):
            reported = simd_level(build, level)
            if reported == level:
                levels.append(level)
        return [Variant(level, build, level) for level in levels]
    return [Variant("new", build)]


def use_bench_venv() -> None:
    """Run under build/bench-venv's interpreter where it exists (fmm3dpy and matplotlib live there)."""
    if VENV_PYTHON.exists() and Path(sys.prefix).resolve() != VENV_PYTHON.parent.parent.resolve():
        os.execv(str(VENV_PYTHON), [str(VENV_PYTHON), str(Path(__file__).resolve()), *sys.argv[1:]])


def main() -> None:
    use_bench_venv()
    args = parse_args()
    RESULTS.mkdir(parents=True, exist_ok=True)
    if not args.render_only:
        build = (ROOT / args.build).resolve()
        groups = selected_groups(args)
        targets = sorted({t for g in groups for t in g.targets})
        if not args.no_build:
            build_targets(ROOT, build, targets)
        variants = make_variants(args, build)
        if args.compare and not args.no_build:
            build_targets(variants[1].build.parent.parent, variants[1].build, targets, like=build)
        for group in groups:
            run = run_group_concurrently if args.concurrent else run_group
            rec = record(group, args, variants, run(group, variants, size_mode(args), args.rounds))
            (RESULTS / results_name(group, variants, args)).write_text(json.dumps(rec, indent=1) + "\n")
            if len(variants) == 1:
                plot(group, rec)
    (ROOT / "bench" / "README.md").write_text(render(load_results()))
    print(f"# wrote {ROOT / 'bench' / 'README.md'}", file=sys.stderr)


if __name__ == "__main__":
    main()
