#!/usr/bin/env python3
"""Settling velocity of a spherical cloud of N spheres against the theory for
a uniform cloud of point forces (Stokeslets), from the runs of run.py.

Mean particle velocity of N point forces F spread uniformly in a sphere of
radius R (pair average <1/r> = 6/(5R) over two points of the ball):
    U = F/(6 pi eta a) + (6/5) (N-1) F/(6 pi eta R)
i.e. a sphere of viscosity ratio 1 (Hadamard-Rybczynski: U = N F/(5 pi eta R)).
R is measured from the initial frame as sqrt(5/3 <|x - x_c|^2>).

    python3 examples/bd/sedimenting_cloud/plot.py [--out DIR] [--png FILE]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
import _analysis as an  # noqa: E402
from run import CASES  # noqa: E402

F, A, ETA = 1.0, 1.0, 1.0  # buoyant weight, radius, viscosity of sedimentation.toml
U0 = F / (6 * np.pi * ETA * A)  # single-sphere Stokes velocity


def measure(run: Path):
    """(N, R, U mean, U standard error, times, v_z series) of one run."""
    log = an.read_log(run / "log.csv")
    traj = an.Trajectory(run / "trajectory.xyz")
    x0 = traj.positions[0]
    R = np.sqrt(5.0 / 3.0 * np.mean(np.sum((x0 - x0.mean(0)) ** 2, axis=1)))
    t, vz = log["time"][1:], -log["mean_vz"][1:]  # row 0 is step 0 (no interval)
    return len(x0), R, vz.mean(), vz.std(ddof=1) / np.sqrt(len(vz)), t, vz


def main() -> int:
    args = an.script_args(__doc__, HERE, "sedimenting_cloud.png")
    _, fig, (ax1, ax2) = an.figure(1, 2, figsize=(11, 4.3))
    print(f"{'run':8} {'N':>5} {'R/a':>6} {'U/U0 BD':>14} {'U/U0 theory':>11} {'ratio':>6}")
    pts = []
    for name, (count, method) in CASES.items():
        n, R, u, du, t, vz = measure(args.out / name)
        theory = U0 * (1 + 1.2 * (n - 1) * A / R) if method != "none" else U0
        print(f"{name:8} {n:5d} {R:6.2f} {u / U0:8.2f} ± {du / U0:4.2f} {theory / U0:11.2f} {u / theory:6.3f}")
        ax1.plot(t, vz / theory, label=f"N={n}" + {"none": " free draining", "pse": " PSE (open)"}.get(method, ""),
                 lw=0.8 if method == "none" else 1.5)
        if method != "none":
            pts.append((1 + 1.2 * (n - 1) * A / R, u / U0, du / U0, n))
    ax1.axhline(1, color="k", ls="--", lw=0.8)
    ax1.set(xlabel=r"time $t$ [$\eta a^3/kT$]", ylabel="mean settling velocity / theory", ylim=(0, 2),
            title=r"clouds at $\phi=0.05$, velocity over each 10 steps")
    ax1.legend(fontsize=8)
    th, u, du, n = map(np.array, zip(*pts))
    ax2.errorbar(th, u, du, fmt="o", label="BD with RPY (mean over $t\\in[0,2]$)")
    for xi, yi, ni in zip(th, u, n):
        ax2.annotate(f"N={ni}", (xi, yi), textcoords="offset points", xytext=(6, -10), fontsize=8)
    xs = np.linspace(0, th.max() * 1.1, 2)
    ax2.plot(xs, xs, "k--", label=r"$U_0\,[1+\frac{6}{5}(N-1)\,a/R]$ (Stokeslet cloud)")
    ax2.axhline(1, color="gray", lw=0.8, label=r"single sphere $U_0=F/6\pi\eta a$")
    ax2.set(xlabel=r"theory $1+\frac{6}{5}(N-1)a/R$", ylabel=r"measured $U/U_0$", xlim=(0, None), ylim=(0, None))
    ax2.legend(fontsize=8, loc="upper left")
    return an.save_figure(fig, args.png)


if __name__ == "__main__":
    sys.exit(main())
