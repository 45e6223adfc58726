#!/usr/bin/env python3
"""LaplaceFmm automatic leaves (fitted grid where it applies) against the bounding-cube tree of
the same automatic capacity (the previous automatic leaves), side by side on the same points.

Usage: PYTHONPATH=build/release/python python3 bench/fmm/fitted_grid.py DISTS NS EPSS [REPEATS [THREADS]]
  e.g. fitted_grid.py cube,sphere 1e4,3e4,1e5,2e5 1e-3,1e-6,1e-9,1e-12
Distributions: cube (uniform), sphere (surface), octant (surface octant), ball (uniform solid ball).
Pot + grad + Hessian at the sources, one density, 1 thread (or THREADS); the two plans' evaluations are
interleaved and the medians of REPEATS (default 7) are compared. Prints both times, the speed-up,
the trees (leaves, capacity, root scale) and both plans' sampled errors against direct sums.
"""
import sys
import time

import numpy as np
import rpyfmm


def points(dist, n, seed=12345):
    rng = np.random.default_rng(seed)
    if dist == "cube":
        return rng.uniform(0.0, 1.0, (n, 3))
    v = rng.standard_normal((n, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    if dist == "ball":  # solid ball, uniform
        return v * rng.uniform(0.0, 1.0, (n, 1)) ** (1.0 / 3.0)
    return np.abs(v) if dist == "octant" else v


def sampled_error(x, q, res, k=300):
    """Largest of the potential, gradient and Hessian relative l2 errors on k sampled sources
    (laplace_direct skips the r = 0 self pair, as the FMM does at the sources)."""
    idx = np.random.default_rng(5).choice(len(x), min(k, len(x)), replace=False)
    ref = rpyfmm.laplace_direct(x, q, targets=x[idx])
    return max(float(np.linalg.norm(res[idx, c0:c1] - ref[:, c0:c1]) / np.linalg.norm(ref[:, c0:c1]))
               for c0, c1 in ((0, 1), (1, 4), (4, 10)))


def main():
    dists, ns, epss = sys.argv[1].split(","), sys.argv[2].split(","), sys.argv[3].split(",")
    repeats = int(sys.argv[4]) if len(sys.argv) > 4 else 7
    rpyfmm.set_num_threads(int(sys.argv[5]) if len(sys.argv) > 5 else 1)
    for dist in dists:
        for n in (int(float(v)) for v in ns):
            x = points(dist, n)
            q = np.random.default_rng(777).uniform(-1.0, 1.0, n)
            for eps in (float(v) for v in epss):
                auto = rpyfmm.LaplaceFmm(tolerance=eps)
                auto.set_points(x)
                cube = rpyfmm.LaplaceFmm(tolerance=eps, leaf_capacity=rpyfmm.fmm_default_leaf_capacity(eps))
                cube.set_points(x)
                plans = {"cube": cube, "auto": auto}
                times = {k: [] for k in plans}
                results = {}
                for _ in range(repeats):
                    for k, p in plans.items():
                        t = time.perf_counter()
                        results[k] = p.evaluate(q)
                        times[k].append(time.perf_counter() - t)
                a, b = np.median(times["cube"]), np.median(times["auto"])
                sa, sb = cube.stats(), auto.stats()
                print(f"{dist:6s} N={n:>7d} eps={eps:.0e}: bounding cube {a:.4f} s ({sa['leaves']} leaves, cap "
                      f"{sa['leaf_capacity']}, level share {sa['leaf_level_share']:.3f}), auto {b:.4f} s "
                      f"({sb['leaves']} leaves, cap {sb['leaf_capacity']}, "
                      f"root {sb['root_scale']:.3f}), speed-up {a / b:.2f}x, err {sampled_error(x, q, results['cube']):.1e}"
                      f" -> {sampled_error(x, q, results['auto']):.1e}", flush=True)


if __name__ == "__main__":
    main()
