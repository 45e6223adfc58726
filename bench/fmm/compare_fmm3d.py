#!/usr/bin/env python3
"""Side-by-side: rpyfmm's LaplaceFmm (bench_fmm) vs fmm3dpy.lfmm3d on the same points.

Usage: compare_fmm3d.py BENCH_FMM [--n 1e5 ...] [--dist cube ...] [--eps 1e-6 ...] [--threads 1 2]
                        [--rounds 3] [--pgt 3] [--json out.jsonl]

For every case and round, runs bench_fmm (which writes its points and charges to .npy, median of
--reps evaluations) and then, in a fresh Python process with OMP_NUM_THREADS set, lfmm3d with the same
points, charges, eps and outputs (pg=3: potential, gradient, Hessian at the sources), alternating the
two so machine noise hits both alike. fmm3dpy's kernel is 1/(4 pi r) and its gradient is +grad; its
errors are measured on the same sampled targets against a direct sum (l3ddir). Reports medians and
the time ratio fmm3dpy / rpyfmm (> 1: rpyfmm faster). Benchmark-only dependency: pip install numpy fmm3dpy.
"""
import argparse, json, os, statistics, subprocess, sys, tempfile

PEER = r"""
import sys, time, resource, json, numpy as np, fmm3dpy
path, eps, pg, nsample = sys.argv[1], float(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
x = np.load(path); q = np.load(path + ".charges.npy")
n = x.shape[0]; nd = q.shape[0]
src = np.ascontiguousarray(x.T); ch = q[0].copy() if nd == 1 else np.ascontiguousarray(q)
t0 = time.perf_counter()
out = fmm3dpy.lfmm3d(eps=eps, sources=src, charges=ch, pg=pg, nd=nd)
t = time.perf_counter() - t0
rng = np.random.default_rng(99); idx = rng.integers(0, n, size=min(nsample, n))
ref = fmm3dpy.l3ddir(sources=src, targets=np.ascontiguousarray(src[:, idx]), charges=ch, pgt=pg, nd=nd)
def rel(a, b): return float(np.linalg.norm(a - b) / np.linalg.norm(b))
e = {"err_pot": rel(out.pot.reshape(nd, n)[:, idx], ref.pottarg.reshape(nd, -1))}
if pg >= 2: e["err_grad"] = rel(out.grad.reshape(nd, 3, n)[..., idx], ref.gradtarg.reshape(nd, 3, -1))
if pg >= 3: e["err_hess"] = rel(out.hess.reshape(nd, 6, n)[..., idx], ref.hesstarg.reshape(nd, 6, -1))
e["time_s"] = t; e["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
print(json.dumps(e))
"""

def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("bench")
    ap.add_argument("--n", nargs="+", default=["1e5"])
    ap.add_argument("--dist", nargs="+", default=["cube"])
    ap.add_argument("--eps", nargs="+", default=["1e-6"])
    ap.add_argument("--threads", nargs="+", type=int, default=[1, 2])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--reps", type=int, default=1)
    ap.add_argument("--pgt", type=int, default=3)
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    outputs = {1: 1, 2: 3, 3: 7}[a.pgt]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in a.n:
            for dist in a.dist:
                for eps in a.eps:
                    for th in a.threads:
                        env = dict(os.environ, OMP_NUM_THREADS=str(th))
                        ours, peer = [], []
                        path = os.path.join(tmp, "pts.npy")
                        for _ in range(a.rounds):
                            r = subprocess.run([a.bench, "--n", n, "--dist", dist, "--eps", eps, "--reps", str(a.reps),
                                                "--outputs", str(outputs), "--npy", path],
                                               env=env, check=True, capture_output=True, text=True)
                            ours.append(json.loads(r.stdout.strip().splitlines()[-1]))
                            r = subprocess.run([sys.executable, "-c", PEER, path, eps, str(a.pgt), "1000"],
                                               env=env, check=True, capture_output=True, text=True)
                            peer.append(json.loads(r.stdout.strip().splitlines()[-1]))
                        t_ours = statistics.median(o["eval_s"] for o in ours)
                        t_peer = statistics.median(p["time_s"] for p in peer)
                        row = {"n": n, "dist": dist, "eps": eps, "threads": th, "rpyfmm_s": t_ours,
                               "rpyfmm_setup_s": statistics.median(o["setup_s"] for o in ours),
                               "fmm3d_s": t_peer, "ratio_fmm3d_over_rpyfmm": t_peer / (t_ours + statistics.median(o["setup_s"] for o in ours)),
                               "rpyfmm": ours[-1], "fmm3d": peer[-1]}
                        rows.append(row)
                        print(json.dumps(row), flush=True)
    if a.json:
        with open(a.json, "w") as f:
            for r in rows: f.write(json.dumps(r) + "\n")

if __name__ == "__main__":
    main()
