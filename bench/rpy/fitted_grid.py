#!/usr/bin/env python3
"""FmmRpy automatic leaves (fitted grid) against the bounding-cube tree (explicit leaf_capacity
OLD_LEAF, the previous default: 150 at 3 digits, 400 at 6), spherical BD cloud phi = 0.05,
1 thread, medians of 7 interleaved products."""
import sys, os, numpy as np, time
# usage: PYTHONPATH=build/release/python python3 bench/rpy/fitted_grid.py EPS N1,N2,... OLD_LEAF
import rpyfmm
rpyfmm.set_num_threads(1)
def cloud(n, phi=0.05, seed=3):
    rng = np.random.default_rng(seed)
    radius = (n / phi) ** (1.0 / 3.0)
    pts = rng.uniform(-radius, radius, (4 * n, 3))
    return pts[np.einsum("ij,ij->i", pts, pts) < radius * radius][:n]
eps=float(sys.argv[1]); old_leaf=int(sys.argv[3])
for N in [int(v) for v in sys.argv[2].split(',')]:
    x=cloud(N); F=np.random.default_rng(0).standard_normal((N,3))
    ops={'cube':rpyfmm.FmmRpy(tolerance=eps, leaf_capacity=old_leaf), 'auto':rpyfmm.FmmRpy(tolerance=eps)}
    for o in ops.values(): o.set_positions(x,np.ones(N))
    ts={k:[] for k in ops}
    for r in range(7):
        for k,o in ops.items():
            t=time.perf_counter(); o.apply(F); ts[k].append(time.perf_counter()-t)
    a,b=np.median(ts['cube']),np.median(ts['auto'])
    print(f"BD cloud N={N} eps={eps}: bounding cube {a*1e3:.1f} ms, auto {b*1e3:.1f} ms, speed-up {a/b:.2f}x", flush=True)
