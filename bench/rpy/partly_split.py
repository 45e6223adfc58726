#!/usr/bin/env python3
"""FmmRpy automatic leaves against the bounding-cube tree of an explicit capacity CAP (the
default capacity: 200 / 400 at 3 / 6 digits with the AVX-512 kernels), side by side on the same
particles: interleaved products, medians of REPEATS (default 5), 1 thread. Prints both trees
(leaves, TreeStats::leaf_level_share, capacity, root scale), the speed-up, and both errors on 200
sampled rows against exact RPY sums (equal radii a = 1, eta = 1; overlapping pairs included).

Usage: PYTHONPATH=build/release/python python3 bench/rpy/partly_split.py DISTS NS EPS CAP [REPEATS]
  e.g. partly_split.py susp,ball 2.6e4,2e5 1e-6 400
DISTS: susp (uniform cube, volume fraction 0.1), ball (uniform ball, volume fraction 0.05).
"""
import sys
import time

import numpy as np
import rpyfmm


def cloud(dist, n, seed=3):
    rng = np.random.default_rng(seed)
    if dist == "ball":
        radius = (n / 0.05) ** (1.0 / 3.0)
        pts = rng.uniform(-radius, radius, (4 * n, 3))
        return pts[np.einsum("ij,ij->i", pts, pts) < radius * radius][:n]
    side = (n * 4.0 * np.pi / 3.0 / 0.1) ** (1.0 / 3.0)
    return rng.uniform(0.0, side, (n, 3))


def exact_rows(x, f, rows):
    """Exact RPY velocities (a = 1, eta = 1) of the given rows: both overlap regimes and the self term."""
    out = np.zeros((len(rows), 3))
    for t, i in enumerate(rows):
        d = x[i] - x
        r = np.linalg.norm(d, axis=1)
        r[i] = 1.0
        e = d / r[:, None]
        far = r >= 2.0
        c1 = np.where(far, (1 + 2 / (3 * r * r)) / (8 * np.pi * r), (1 - 9 * r / 32) / (6 * np.pi))
        c2 = np.where(far, (1 - 2 / (r * r)) / (8 * np.pi * r), (3 * r / 32) / (6 * np.pi))
        c1[i], c2[i] = 1 / (6 * np.pi), 0.0
        out[t] = (c1[:, None] * f).sum(0) + ((c2 * np.einsum("ij,ij->i", e, f))[:, None] * e).sum(0)
    return out


def main():
    dists, ns, eps, cap = sys.argv[1].split(","), sys.argv[2].split(","), float(sys.argv[3]), int(sys.argv[4])
    repeats = int(sys.argv[5]) if len(sys.argv) > 5 else 5
    rpyfmm.set_num_threads(1)
    for dist in dists:
        for n in (int(float(v)) for v in ns):
            x = cloud(dist, n)
            f = np.random.default_rng(0).standard_normal((n, 3))
            ops = {"cube": rpyfmm.FmmRpy(tolerance=eps, leaf_capacity=cap), "auto": rpyfmm.FmmRpy(tolerance=eps)}
            for op in ops.values():
                op.set_positions(x, np.ones(n))
            times, u = {k: [] for k in ops}, {}
            for _ in range(repeats):
                for k, op in ops.items():
                    t = time.perf_counter()
                    u[k] = op.apply(f)
                    times[k].append(time.perf_counter() - t)
            rows = np.random.default_rng(1).choice(n, 200, replace=False)
            ref = exact_rows(x, f, rows)
            err = {k: np.linalg.norm(u[k][rows] - ref) / np.linalg.norm(ref) for k in u}
            a, b = np.median(times["cube"]), np.median(times["auto"])
            sc, sa = ops["cube"].stats(), ops["auto"].stats()
            print(f"{dist} N={n} eps={eps:.0e}: cube {a:.3f}s ({sc['leaves']} lv, share {sc['leaf_level_share']:.3f}), "
                  f"auto {b:.3f}s ({sa['leaves']} lv, cap {sa['leaf_capacity']}, root {sa['root_scale']:.3f}) "
                  f"speed-up {a / b:.2f}x, err {err['cube']:.1e} -> {err['auto']:.1e}", flush=True)


if __name__ == "__main__":
    main()
