#!/usr/bin/env python3
"""Side-by-side: rpyfmm's direct Laplace kernel (bench_direct) vs fmm3dpy.l3ddir.

Usage: compare_fmm3d.py BENCH_DIRECT [--n 10000] [--reps 5] [--threads 1 2] [--rounds 3]

For each thread count and round, runs bench_direct (median of --reps) and, in a
fresh Python process with OMP_NUM_THREADS set, fmm3dpy.l3ddir on exactly the
same points and charges (dumped by bench_direct), alternating the two so that
machine noise hits both alike. Reports median times and pairs/s per case and
the ratio fmm3dpy time / rpyfmm time (> 1: rpyfmm faster).
Also reports the ratio of process CPU times (robust on a loaded machine).
Correctness is checked once: rpyfmm's values times 1/(4 pi) must equal l3ddir's
(same sign convention: l3ddir's gradient is +grad of the potential).
Needs `pip install numpy fmm3dpy` (benchmark only; not a build dependency).
"""
import argparse
import os
import statistics
import subprocess
import sys
import tempfile

FMM3D_TIMER = r"""
import sys, time, numpy as np, fmm3dpy
n, nd, reps, path = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
raw = np.fromfile(path, dtype=np.float64)
src = np.ascontiguousarray(raw[:3 * n].reshape(n, 3).T)
q = raw[3 * n:3 * n + nd * n].reshape(nd, n) if nd > 1 else raw[3 * n:4 * n].copy()
for pgt, name in ((1, "pot"), (2, "pot+grad"), (3, "pot+grad+hess")):
    fmm3dpy.l3ddir(sources=src, targets=src, charges=q, pgt=pgt, nd=nd)  # warm-up
    ts, cs = [], []
    for _ in range(reps):
        c0, t0 = time.process_time(), time.perf_counter()
        fmm3dpy.l3ddir(sources=src, targets=src, charges=q, pgt=pgt, nd=nd)
        ts.append(time.perf_counter() - t0)
        cs.append(time.process_time() - c0)
    ts.sort(); cs.sort()
    print(name, ts[len(ts) // 2], cs[len(cs) // 2])
if len(sys.argv) > 5:  # correctness check against rpyfmm's results (.npy-free raw file)
    out = fmm3dpy.l3ddir(sources=src, targets=src, charges=q, pgt=3, nd=nd)
    ref = np.fromfile(sys.argv[5], dtype=np.float64).reshape(nd, n, 10) / (4 * np.pi)
    pot = out.pottarg.reshape(nd, n); grad = out.gradtarg.reshape(nd, 3, n); hess = out.hesstarg.reshape(nd, 6, n)
    e = max(np.abs(pot - ref[:, :, 0]).max() / np.abs(ref[:, :, 0]).max(),
            np.abs(grad - ref[:, :, 1:4].transpose(0, 2, 1)).max() / np.abs(ref[:, :, 1:4]).max(),
            np.abs(hess - ref[:, :, 4:10].transpose(0, 2, 1)).max() / np.abs(ref[:, :, 4:10]).max())
    print("maxrelerr", e)
"""


def run_ours(bench, n, nd, threads, reps, dump, results=None):
    args = [bench, "--n", str(n), "--nd", str(nd), "--threads", str(threads), "--reps", str(reps),
            "--kernel", "laplace", "--dump", dump] + (["--results", results] if results else [])
    out = subprocess.run(args, check=True, capture_output=True, text=True).stdout
    rows = {}
    for line in out.splitlines()[1:]:
        f = line.split(",")
        rows[f[1]] = (float(f[5]), float(f[7]))  # wall median, CPU median
    return rows


def run_fmm3d(n, nd, threads, reps, dump, check=None):
    env = dict(os.environ, OMP_NUM_THREADS=str(threads))
    args = [sys.executable, "-c", FMM3D_TIMER, str(n), str(nd), str(reps), dump] + ([check] if check else [])
    out = subprocess.run(args, check=True, capture_output=True, text=True, env=env).stdout
    rows = {}
    for line in out.splitlines():
        f = line.split()
        rows[f[0]] = float(f[1]) if len(f) == 2 else (float(f[1]), float(f[2]))
    return rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("bench")
    ap.add_argument("--n", type=int, default=10000)
    ap.add_argument("--nd", type=int, default=1)
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        dump = os.path.join(tmp, "points.bin")
        pairs = a.n * (a.n - 1) * a.nd
        results = os.path.join(tmp, "results.bin")
        run_ours(a.bench, a.n, a.nd, 1, 1, dump, results)
        err = run_fmm3d(a.n, a.nd, 1, 1, dump, results)["maxrelerr"]
        print(f"# N = {a.n}, nd = {a.nd}, pairs = {pairs:.3g}; medians over {a.rounds} alternating rounds x {a.reps} reps")
        print(f"# accuracy: max relative difference rpyfmm/(4 pi) vs l3ddir (pot, grad, Hessian): {err:.2e}")
        print("| outputs | threads | rpyfmm wall s | fmm3dpy wall s | rpyfmm Mpairs/s | fmm3dpy Mpairs/s"
              " | speed-up (wall) | speed-up (CPU time) |")
        print("|---|---|---|---|---|---|---|---|")
        for t in a.threads:
            ours, theirs = {}, {}
            for _ in range(a.rounds):
                for k, v in run_ours(a.bench, a.n, a.nd, t, a.reps, dump).items():
                    ours.setdefault(k, []).append(v)
                for k, v in run_fmm3d(a.n, a.nd, t, a.reps, dump).items():
                    theirs.setdefault(k, []).append(v)
            for k in ("pot", "pot+grad", "pot+grad+hess"):
                ow = statistics.median(v[0] for v in ours[k])
                oc = statistics.median(v[1] for v in ours[k])
                fw = statistics.median(v[0] for v in theirs[k])
                fc = statistics.median(v[1] for v in theirs[k])
                print(f"| {k} | {t} | {ow:.4f} | {fw:.4f} | {pairs / ow / 1e6:.0f} | {pairs / fw / 1e6:.0f}"
                      f" | {fw / ow:.2f}x | {fc / oc:.2f}x |", flush=True)


if __name__ == "__main__":
    main()
