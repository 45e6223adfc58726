#!/usr/bin/env python3
"""Plots compare_fmm3d.py results (JSON lines): evaluation time vs N per distribution and tolerance,
rpyfmm vs fmm3dpy, one and two threads (OUT); measured error vs requested eps (OUT_errors.png). Needs matplotlib (benchmark-only dependency).

Usage: plot_fmm.py results.jsonl [more.jsonl ...] --out fmm_times.png
"""
import argparse, json
from collections import defaultdict

def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("files", nargs="+")
    ap.add_argument("--out", default="fmm_times.png")
    a = ap.parse_args()
    rows = [json.loads(l) for f in a.files for l in open(f) if l.strip()]
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    keys = sorted({(r["dist"], r["eps"]) for r in rows})
    fig, axes = plt.subplots(1, len(keys), figsize=(4 * len(keys), 3.5), squeeze=False)
    for ax, (dist, eps) in zip(axes[0], keys):
        series = defaultdict(list)
        for r in rows:
            if (r["dist"], r["eps"]) != (dist, eps):
                continue
            n = float(r["n"])
            series[("rpyfmm", r["threads"])].append((n, r["rpyfmm_s"]))
            series[("fmm3dpy", r["threads"])].append((n, r["fmm3d_s"]))
        for (who, th), pts in sorted(series.items()):
            pts.sort()
            ax.loglog([p[0] for p in pts], [p[1] for p in pts], "o-" if who == "rpyfmm" else "s--",
                      label=f"{who}, {th} thr")
        ax.set_title(f"{dist}, eps={eps}")
        ax.set_xlabel("N")
        ax.set_ylabel("time [s] (pot+grad+Hessian)")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(a.out, dpi=120)

    # Error vs eps: measured relative l2 error of each output (rpyfmm and fmm3dpy) against the
    # requested tolerance, all distributions and sizes (the contract is error <= eps).
    fig, axes = plt.subplots(1, 3, figsize=(13, 4))
    for ax, out in zip(axes, ("pot", "grad", "hess")):
        for who, key, marker in (("rpyfmm", "rpyfmm", "o"), ("fmm3dpy", "fmm3d", "s")):
            xs = [float(r["eps"]) for r in rows if r["threads"] == 1]
            ys = [r[key]["err_" + out] for r in rows if r["threads"] == 1]
            ax.loglog(xs, ys, marker, alpha=0.6, label=who)
        ax.loglog([1e-10, 1e-2], [1e-10, 1e-2], "k-", label="error = eps")
        ax.set_xlabel("requested eps")
        ax.set_ylabel(f"relative l2 error ({out})")
        ax.set_title({"pot": "potential", "grad": "gradient", "hess": "Hessian"}[out])
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(a.out.replace(".png", "") + "_errors.png", dpi=120)

if __name__ == "__main__":
    main()
