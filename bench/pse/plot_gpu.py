#!/usr/bin/env python3
"""Plots `bench_pse --cuda` output: particle-timesteps per second (PTPS) vs N on the GPU.

usage: python3 bench/pse/plot_gpu.py NEW.csv PREVIOUS.csv OUT.png
   e.g. python3 bench/pse/plot_gpu.py bench/pse/results_gpu_session20.csv \\
            bench/pse/results_gpu_session20_first.csv bench/pse/pse_gpu_ptps.png

Curves (Table I setup: phi = 0.1, xi a = 0.5, tolerance 1e-3): the defaults' rows (the first
row of each N) of NEW for M F and the split sampler M^1/2 z with host arrays (transfers
counted) and with device arrays, and one Brownian step (set_positions + apply_with_noise, host
arrays); dashed, the first row of each N of PREVIOUS (the version before). Horizontal lines:
the issue's targets (50e6 / 30e6 PTPS at N ~ 1e6) and the paper's K40 figures (~5e6 / ~3e6).
"""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def first_rows(path: str) -> list[dict]:
    with open(path) as f:
        rows = list(csv.DictReader(line for line in f if line.strip() and not line.startswith("#")))
    seen, out = set(), []
    for r in rows:
        if r["N"] not in seen:
            seen.add(r["N"])
            out.append(r)
    return sorted(out, key=lambda r: int(r["N"]))


def main(new_path: str, previous_path: str, out: str) -> None:
    new, previous = first_rows(new_path), first_rows(previous_path)
    plt.figure(figsize=(6.6, 4.6))
    curves = [("MF_PTPS", "M F, host arrays", "o-"), ("MF_dev_PTPS", "M F, device arrays", "o--"),
              ("sample_PTPS", "M^1/2 z, host arrays", "s-"), ("sample_dev_PTPS", "M^1/2 z, device arrays", "s--")]
    for key, label, style in curves:
        plt.loglog([int(r["N"]) for r in new], [float(r[key]) for r in new], style, label=label)
    if "step_PTPS" in new[0]:
        plt.loglog([int(r["N"]) for r in new], [float(r["step_PTPS"]) for r in new], "^-",
                   label="BD step (set_positions + U = M F + M^1/2 z)")
    for key, label, marker in (("MF_PTPS", "previous: M F, host arrays", "x"),
                               ("MF_dev_PTPS", "previous: M F, device arrays", "+")):
        plt.loglog([int(r["N"]) for r in previous], [float(r[key]) for r in previous], ":", color="grey",
                   marker=marker, markersize=8, label=label)
    plt.axhline(50e6, color="tab:red", lw=0.8, ls="-.", label="target M F (10x K40)")
    plt.axhline(30e6, color="tab:purple", lw=0.8, ls="-.", label="target M^1/2 z (10x K40)")
    plt.axhline(5e6, color="black", lw=0.6, ls=":", label="[PSE] K40: M F ~5e6")
    plt.xlabel("N (phi = 0.1, xi a = 0.5, tolerance 1e-3)")
    plt.ylabel("particle-timesteps per second, one H200")
    plt.grid(True, which="both", alpha=0.3)
    plt.legend(fontsize=7, loc="lower right")
    plt.tight_layout()
    plt.savefig(out, dpi=110)


if __name__ == "__main__":
    if len(sys.argv) != 4:
        print(__doc__)
        sys.exit(2)
    main(*sys.argv[1:])
