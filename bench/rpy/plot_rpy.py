#!/usr/bin/env python3
"""Plots of the free-space RPY benchmark: time of one product vs N (rpyfmm FmmRpy at
3/6/9 digits, direct O(N^2), fmm3dpy stfmm3d) and the measured error vs the requested
tolerance. Input: the CSV printed by bench_rpy_fmm and the one printed by
compare_stfmm3d.py. usage: plot_rpy.py rpy.csv stfmm3d.csv out.png"""
import csv
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt


def main():
    rpy = [r for r in csv.DictReader(open(sys.argv[1])) if r.get("dist") and r["dist"] != "dist"]
    st = [line.strip().split(",") for line in open(sys.argv[2]) if line.startswith("stfmm3d")]
    dists = sorted({r["dist"] for r in rpy})
    fig, axes = plt.subplots(1, len(dists) + 1, figsize=(5 * (len(dists) + 1), 4))
    for ax, dist in zip(axes, dists):
        rows = [r for r in rpy if r["dist"] == dist and r["threads"] == "1"]
        for eps in sorted({r["eps"] for r in rows}, key=float, reverse=True):
            sel = sorted((int(r["N"]), float(r["rpy_s"])) for r in rows if r["eps"] == eps)
            ax.loglog(*zip(*sel), "o-", label=f"rpyfmm eps={eps}")
        direct = sorted({(int(r["N"]), float(r["direct_s"])) for r in rows})
        ax.loglog(*zip(*direct), "k--", label="direct O(N^2)")
        ax.set_title(f"{dist}: one RPY product, 1 thread")
        ax.set_xlabel("N")
        ax.set_ylabel("seconds")
        ax.legend(fontsize=7)
    # stfmm3d rows: stfmm3d,dist,N,eps,seconds
    for ax, dist in zip(axes, dists):
        for eps in sorted({s[3] for s in st if s[1] == dist}, key=float, reverse=True):
            sel = sorted({(int(s[2]), float(s[4])) for s in st if s[1] == dist and s[3] == eps})
            ax.loglog(*zip(*sel), "s:", label=f"fmm3dpy stfmm3d eps={eps}")
        ax.legend(fontsize=7)
    ax = axes[-1]
    for dist in dists:
        rows = [r for r in rpy if r["dist"] == dist]
        ax.loglog([float(r["eps"]) for r in rows], [float(r["rel_l2_err"]) for r in rows], "o", label=dist)
    ax.loglog([1e-10, 1e-2], [1e-10, 1e-2], "k-", label="error = eps")
    ax.set_xlabel("requested eps")
    ax.set_ylabel("measured relative l2 error")
    ax.set_title("accuracy contract")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(sys.argv[3], dpi=110)


if __name__ == "__main__":
    main()
