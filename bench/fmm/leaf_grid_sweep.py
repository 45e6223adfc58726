#!/usr/bin/env python3
"""Laplace FMM: automatic leaves against leaves fitted to a target occupancy (fit_leaf_grid).

Usage: python3 bench/fmm/leaf_grid_sweep.py BENCH_FMM DISTS NS EPSS OCCUPANCIES [OUT.jsonl]
  e.g. leaf_grid_sweep.py build/release/bench/fmm/bench_fmm cube,sphere 1e5,2e5 1e-6 0,36,50,70
Occupancy 0 = the automatic leaves. Pot + grad + Hessian at the sources, one density, 1 thread,
median of 3 evaluations per row (bench_fmm); prints seconds, points per leaf and the errors.
"""
import json
import os
import subprocess
import sys


def main():
    bench, dists, ns, epss, occs = sys.argv[1:6]
    out = open(sys.argv[6], "a") if len(sys.argv) > 6 else None
    env = dict(os.environ, OMP_NUM_THREADS="1")
    for dist in dists.split(","):
        for n in ns.split(","):
            for eps in epss.split(","):
                for occ in occs.split(","):
                    cmd = [bench, "--n", n, "--dist", dist, "--eps", eps, "--reps", "3", "--sample", "300",
                           "--occupancy", occ]
                    row = json.loads(subprocess.run(cmd, env=env, capture_output=True, text=True, check=True).stdout)
                    row["occupancy"] = int(occ)
                    print(f"{dist:7s} N={n:>5s} eps={eps} occ={occ:>4s}: {row['eval_s']:.4f} s, "
                          f"{row['leaves']:5d} leaves ({float(n) / row['leaves']:5.1f} pts), leaf {row['leaf']}, "
                          f"root {row['root_scale']:.3f}, err {row['err_pot']:.1e}/{row['err_grad']:.1e}/"
                          f"{row['err_hess']:.1e}", flush=True)
                    if out:
                        out.write(json.dumps(row) + "\n")
                        out.flush()


if __name__ == "__main__":
    main()
