"""Sweep of the Ewald parameter xi for the PSE operator: the time of one BD step's mobility work
(set_positions, then apply_with_noise: M F plus the split sampler's M^{1/2} z, sharing the
wave-space FFTs) and of one product M F after set_positions, at fixed xi a, against what the
automatic choice (xi = 0, the cost model of PseOptions::cost_*) picks. Used to calibrate the
cost-model constants (bench/pse/RESULTS.md). Every timed call follows set_positions, as in a
time step, so the real-space pair cache is refilled each time (since session 13; before, the
step excluded set_positions).

usage: PYTHONPATH=build/release/python OMP_NUM_THREADS=1 python3 bench/pse/xi_sweep.py [N ...]
Random points (overlaps allowed) at volume fraction 0.1, a = 1, tolerance 1e-3 by default
(--tol), medians of --reps calls. Prints CSV: N, xi_a (or auto), grid, P, r_cut, step_s, MF_s.
"""
import argparse
import time

import numpy as np
import rpyfmm


def median_time(fn, reps, setup=None):
    times = []
    for _ in range(reps):
        if setup is not None:
            setup()
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("sizes", nargs="*", type=int, default=[8000, 32000, 128000])
    ap.add_argument("--tol", type=float, default=1e-3)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--xi", type=float, nargs="*", default=[0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 1.0, 1.2])
    args = ap.parse_args()
    print("N,xi_a,grid,P,r_cut,step_s,MF_s")
    for n in args.sizes:
        L = (n * 4.0 / 3.0 * np.pi / 0.1) ** (1.0 / 3.0)
        rng = np.random.default_rng(7)
        x = rng.uniform(0.0, L, size=(n, 3))
        f = rng.standard_normal((n, 3))
        for xa in [0.0] + list(args.xi):
            try:
                op = rpyfmm.PseRpy(box=L, tolerance=args.tol, xi=xa)
                op.set_positions(x, 1.0)
            except rpyfmm.Error as e:
                print(f"# N={n} xi a={xa}: {e}")
                continue
            p = op.parameters
            op.apply(f)  # warm-up
            def step():
                op.set_positions(x, 1.0)
                op.apply_with_noise(f, 1.0, 5, 1)

            step_s = median_time(step, args.reps)
            mf = median_time(lambda: op.apply(f), args.reps, setup=lambda: op.set_positions(x, 1.0))
            label = f"auto({p['xi']:.3g})" if xa == 0.0 else f"{xa:.2f}"
            grid = "x".join(str(g) for g in p["grid"])
            print(f"{n},{label},{grid},{p['support'][0]},{p['r_cut']:.3f},{step_s:.4g},{mf:.4g}", flush=True)


if __name__ == "__main__":
    main()
