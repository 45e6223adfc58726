#!/usr/bin/env python3
"""fmm3dpy's Stokes FMM (stfmm3d, Stokeslet velocity only) on the points that
bench_rpy_fmm dumped, timed in the same session: the nearest public peer of
the free-space RPY product.

usage: compare_stfmm3d.py points.bin.N [eps ...]   (set OMP_NUM_THREADS for threads)
"""
import sys
import time

import numpy as np
import fmm3dpy


def main():
    path = sys.argv[1]
    epss = [float(e) for e in sys.argv[2:]] or [1e-3, 1e-6, 1e-9]
    raw = np.fromfile(path, dtype=np.float64)
    n = raw.size // 6
    x = raw[: 3 * n].reshape(n, 3).T.copy()
    f = raw[3 * n:].reshape(n, 3).T.copy()
    for eps in epss:
        times = []
        for _ in range(3):
            t0 = time.perf_counter()
            fmm3dpy.stfmm3d(eps=eps, sources=x, stoklet=f, ifppreg=1)
            times.append(time.perf_counter() - t0)
        print(f"stfmm3d,{n},{eps:.0e},{sorted(times)[1]:.4f}")


if __name__ == "__main__":
    main()
