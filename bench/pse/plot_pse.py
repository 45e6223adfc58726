#!/usr/bin/env python3
"""Plots bench_pse output: particle-timesteps per second (PTPS) vs N, 1 thread.

usage: python3 bench/pse/plot_pse.py bench/pse/results_cpu_1thread.csv bench/pse/pse_ptps.png

Curves: PSE M F, PSE split sampler M^1/2 z, generic Lanczos on the full PSE operator
([PSE] Fig. 6), and the free-space FMM operator on the same particles (M F and a Lanczos
sample), all at tolerance 1e-3, from the '#' lines and rows that bench_pse prints.
"""
import re
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main(path: str, out: str) -> None:
    rows, fmm = [], {}
    for line in open(path):
        m = re.match(r"# N=(\d+) free-space FMM 1 thread: M F ([\d.e+-]+) s .*Lanczos sample ([\d.e+-]+) s", line)
        if m:
            fmm[int(m.group(1))] = (float(m.group(2)), float(m.group(3)))
            continue
        if line.startswith(("#", "N,")) or not line.strip():
            continue
        f = line.strip().split(",")
        if f[1] != "1":
            continue
        rows.append((int(f[0]), float(f[5]), float(f[7]), float(f[11])))
    n = [r[0] for r in rows]
    plt.figure(figsize=(6.4, 4.4))
    plt.loglog(n, [r[0] / r[1] for r in rows], "o-", label="PSE  M F")
    plt.loglog(n, [r[0] / r[2] for r in rows], "s-", label="PSE  M^1/2 z (split sampler)")
    plt.loglog(n, [r[0] / r[3] for r in rows], "^--", label="PSE  Lanczos on full M")
    nf = sorted(fmm)
    plt.loglog(nf, [k / fmm[k][0] for k in nf], "o:", label="free-space FMM  M F")
    plt.loglog(nf, [k / fmm[k][1] for k in nf], "s:", label="free-space FMM  Lanczos M^1/2 z")
    plt.xlabel("N (phi = 0.1, xi a = 0.5, tolerance 1e-3)")
    plt.ylabel("particle-timesteps per second, 1 thread")
    plt.grid(True, which="both", alpha=0.3)
    plt.legend(fontsize=8)
    plt.tight_layout()
    plt.savefig(out, dpi=110)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
