#!/usr/bin/env python3
"""fmm3dpy's Stokes FMM (stfmm3d, Stokeslet velocity only) on the points that
bench_rpy_fmm dumped, timed in the same session: the nearest public peer of
the free-space RPY product.

usage: compare_stfmm3d.py DIST.bin.N [eps ...]   (set OMP_NUM_THREADS for threads)
prints: stfmm3d,DIST,N,eps,seconds (median of 3 runs, 1 run above N = 2e5)
"""
import os
import sys
import time

import numpy as np
import fmm3dpy


def main():
    path = sys.argv[1]
    epss = [float(e) for e in sys.argv[2:]] or [1e-3, 1e-6, 1e-9]
    dist = os.path.basename(path).split(".bin")[0]
    raw = np.fromfile(path, dtype=np.float64)
    n = raw.size // 6
    x = raw[: 3 * n].reshape(n, 3).T.copy()
    f = raw[3 * n:].reshape(n, 3).T.copy()
    for eps in epss:
        times = []
        for _ in range(3 if n <= 200000 else 1):
            t0 = time.perf_counter()
            fmm3dpy.stfmm3d(eps=eps, sources=x, stoklet=f, ifppreg=1)
            times.append(time.perf_counter() - t0)
        print(f"stfmm3d,{dist},{n},{eps:.0e},{sorted(times)[len(times) // 2]:.4f}", flush=True)


if __name__ == "__main__":
    main()
