#!/usr/bin/env python3
"""One-product crossover of FmmRpy against DirectRpy (what `default_fmm_crossover` encodes).

Usage: PYTHONPATH=build/release/python python3 bench/bd/crossover.py EPS N1,N2,... [LEAF1,LEAF2,...]
Random spherical cloud of unit spheres at phi = 0.05 (as bench_bd), 1 thread, median of 5
products per operator; prints milliseconds per product (leaf 0 = the automatic leaf capacity).
"""
import sys
import time

import numpy as np
import rpyfmm


def cloud(n, phi=0.05, seed=3):
    rng = np.random.default_rng(seed)
    radius = (n / phi) ** (1.0 / 3.0)  # n unit spheres fill phi of the ball
    pts = rng.uniform(-radius, radius, (4 * n, 3))
    return pts[np.einsum("ij,ij->i", pts, pts) < radius * radius][:n]


def median_ms(op, forces, repeats=5):
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        op.apply(forces)
        times.append(time.perf_counter() - t)
    return 1e3 * float(np.median(times))


def main():
    rpyfmm.set_num_threads(1)
    eps = float(sys.argv[1])
    sizes = [int(v) for v in sys.argv[2].split(",")]
    leaves = [int(v) for v in (sys.argv[3] if len(sys.argv) > 3 else "0").split(",")]
    print("eps,N,direct_ms," + ",".join(f"fmm_leaf{leaf}_ms" for leaf in leaves) + ",default_crossover")
    for n in sizes:
        x = cloud(n)
        forces = np.random.default_rng(0).standard_normal((n, 3))
        direct = rpyfmm.DirectRpy()
        direct.set_positions(x, np.ones(n))
        row = [f"{eps:.0e}", str(n), f"{median_ms(direct, forces):.1f}"]
        for leaf in leaves:
            fmm = rpyfmm.FmmRpy(tolerance=eps, leaf_capacity=leaf)
            fmm.set_positions(x, np.ones(n))
            row.append(f"{median_ms(fmm, forces):.1f}")
        row.append(str(rpyfmm.default_fmm_crossover(eps)))
        print(",".join(row), flush=True)


if __name__ == "__main__":
    main()
