#!/usr/bin/env python3
"""Python-call overhead of MobilityOperator.apply against the same C++ call.

For N = 1e3 and 1e5 (FmmRpy at tolerance 1e-3, and DirectRpy at N = 1e3), one
OpenMP thread: the median of `--repeats` calls of

  * C++:    op.apply(F, U) timed in C++ around the call (rpyfmm._rpyfmm._time_apply_cpp),
  * Python: time.perf_counter() around op.apply(F, out=U) (float64 views, no copy),
  * Python, new array: op.apply(F) (allocates the result),
  * Python, float32 input: op.apply(F32, out=U) (one documented conversion copy).

Overhead = (Python median - C++ median) / C++ median. Run from the repo root:
  PYTHONPATH=build/release/python python3 bench/python/bench_overhead.py
"""

from __future__ import annotations

import argparse
import statistics
import time
import timeit

import numpy as np

import rpyfmm
from rpyfmm import _rpyfmm


def suspension(n: int, seed: int = 0) -> np.ndarray:
    """n spheres of radius 1 on a jittered cubic lattice (volume fraction ~0.1)."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(n ** (1 / 3)))
    grid = np.stack(np.meshgrid(*[np.arange(side)] * 3, indexing="ij"), -1).reshape(-1, 3)[:n]
    return grid * 3.5 + rng.uniform(-0.5, 0.5, (n, 3))


def median_seconds(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", type=int, nargs="+", default=[1000, 100000])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    rpyfmm.set_num_threads(args.threads)

    print(f"rpyfmm {rpyfmm.__version__}, {args.threads} thread(s), median of {args.repeats} calls")
    print("| operator | N | C++ apply (ms) | Python apply(F, out=U) (ms) | overhead | "
          "Python apply(F) (ms) | overhead | Python float32 F (ms) | overhead |")
    print("|---|---|---|---|---|---|---|---|---|")
    for n in args.sizes:
        ops = [("FmmRpy 1e-3", rpyfmm.FmmRpy(tolerance=1e-3))]
        if n <= 5000:
            ops.append(("DirectRpy", rpyfmm.DirectRpy()))
        x = suspension(n)
        f = np.random.default_rng(1).standard_normal((n, 3))
        f32 = f.astype(np.float32)
        u = np.empty_like(f)
        for label, op in ops:
            op.set_positions(x, 1.0)
            op.apply(f, out=u)  # warm-up
            # Interleave the C++ and Python timings so that load changes hit both alike.
            cpp, py, py_new, py32 = [], [], [], []
            for _ in range(args.repeats):
                cpp += _rpyfmm._time_apply_cpp(op, f, u, 1)
                py.append(median_seconds(lambda: op.apply(f, out=u), 1))
                py_new.append(median_seconds(lambda: op.apply(f), 1))
                py32.append(median_seconds(lambda: op.apply(f32, out=u), 1))
            c = statistics.median(cpp)
            row = [label, f"{n:.0e}", f"{1e3 * c:.3f}"]
            for t in (py, py_new, py32):
                m = statistics.median(t)
                row += [f"{1e3 * m:.3f}", f"{100 * (m - c) / c:+.2f} %"]
            print("| " + " | ".join(row) + " |", flush=True)

    # The binding's own cost per call, where the C++ work is negligible (N = 10, free draining).
    op = rpyfmm.FreeDraining()
    op.set_positions(suspension(10), 1.0)
    f, u = np.ones((10, 3)), np.empty((10, 3))
    per_call = lambda fn: min(timeit.repeat(fn, number=20000, repeat=5)) / 20000  # noqa: E731
    cpp = statistics.median(_rpyfmm._time_apply_cpp(op, f, u, 20000))
    print(f"\nper call, N = 10 free draining: C++ apply {1e6 * cpp:.2f} us; Python apply(F, out=U) "
          f"{1e6 * per_call(lambda: op.apply(f, out=u)):.2f} us; apply(F) {1e6 * per_call(lambda: op.apply(f)):.2f} us; "
          f"apply(F.tolist()) {1e6 * per_call(lambda: op.apply(f.tolist())):.2f} us")


if __name__ == "__main__":
    main()
