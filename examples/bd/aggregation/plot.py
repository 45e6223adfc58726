#!/usr/bin/env python3
"""Number of aggregates against time (Tran et al. (2015), Fig. 3) from the runs of
run.py. An aggregate is a connected group of at least two particles, two
particles being connected when their centres are closer than 1.1 (a_i + a_j)
(the 36-18 well, 14 kT deep at 1.039 (a_i + a_j), is still -8 kT at 1.1 and
-2 kT at 1.2), with periodic minimum images.

    python3 examples/bd/aggregation/plot.py [--out DIR] [--png FILE]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
import _analysis as an  # noqa: E402
from run import CASES, DECADES  # noqa: E402

LINK = 1.1  # contact criterion, in units of a_i + a_j
TAU_D = 6 * np.pi  # a^2 / D0 with a = eta = kT = 1


def count_aggregates(run: Path):
    """(times, number of aggregates of >= 2, mean aggregate size, monomer fraction) over the pieces of a run;
    cached in RUN/aggregates.csv (delete it after re-running)."""
    cache = run / "aggregates.csv"
    if cache.exists():
        return np.loadtxt(cache, delimiter=",", ndmin=2)
    seen, rows = set(), []
    for k in range(DECADES):
        path = run / f"piece{k}" / "trajectory.xyz"
        if not path.exists():
            continue
        traj = an.Trajectory(path)
        for t, s, x in zip(traj.times, traj.steps, traj.positions):
            if s in seen or t == 0:
                continue
            seen.add(s)
            sizes = np.bincount(an.clusters(x, traj.radii, LINK, traj.box))
            agg = sizes[sizes >= 2]
            rows.append((t, len(agg), agg.mean() if len(agg) else 0.0, np.sum(sizes == 1) / len(x)))
    rows = np.array(sorted(rows))
    if rows.size:
        np.savetxt(cache, rows, delimiter=",", header="time,aggregates,mean_size,monomer_fraction")
    return rows


def main() -> int:
    args = an.script_args(__doc__, HERE, "aggregation.png")
    _, fig, (ax1, ax2) = an.figure(1, 2, figsize=(11, 4.3))
    for name, (count, phi, method, steps) in CASES.items():
        rows = count_aggregates(args.out / name)
        if rows.size == 0:
            print(f"{name}: no output in {args.out / name} (run run.py)")
            continue
        t, n_agg, size, free = rows.T
        peak = np.argmax(n_agg)
        print(f"{name:9} N={count:4d} phi={phi:.2f} {method:4}: peak {n_agg[peak]:4.0f} aggregates at t = "
              f"{t[peak]:7.3f} ({t[peak] / TAU_D:.3g} a^2/D0); at t = {t[-1]:g}: {n_agg[-1]:.0f} aggregates, "
              f"mean size {size[-1]:.1f}, {free[-1] * 100:.1f} % monomers")
        if count == 1000:
            ax1.plot(t / TAU_D, n_agg, label=f"$\\phi$ = {phi:.2f}")
        if phi == 0.10 and count == 300:
            style = "-" if method == "none" else "--"
            label = "free draining" if method == "none" else "RPY (PSE)"
            ax2.plot(t / TAU_D, n_agg, style, label=f"{label}: aggregates")
            ax2.plot(t / TAU_D, free * count, style, lw=0.8, label=f"{label}: single particles")
    ax1.set(xscale="log", xlabel=r"time $t\,D_0/a^2$", ylabel="number of aggregates (≥ 2 particles)",
            title="1000 particles, free draining (cf. Tran et al. (2015), Fig. 3)")
    ax1.legend(fontsize=8)
    ax2.set(xscale="log", yscale="log", xlabel=r"time $t\,D_0/a^2$", ylabel="count",
            title=r"300 particles, $\phi = 0.10$: HI vs free draining")
    ax2.legend(fontsize=8)
    return an.save_figure(fig, args.png)


if __name__ == "__main__":
    sys.exit(main())
