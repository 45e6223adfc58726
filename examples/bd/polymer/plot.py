#!/usr/bin/env python3
"""Centre-of-mass diffusion coefficient D(N) of bead-spring chains with and
without hydrodynamic interactions, from the runs of run.py.

D = MSD_cm(t)/(6t) of the centre of mass at the shortest lag t = 1 (20
steps), averaged over chains and time origins (the least noisy estimate; the
right panel shows MSD_cm/6t up to t = 20: flat within the noise). Theory lines:
  * Rouse (free draining): D = D0 / N exactly (internal forces cancel in the
    centre of mass; D0 = kT/(6 pi eta a)).
  * Kirkwood (HI): D_K = kT/N^2 sum_ij <tr mu_ij>/3, the exact short-time value
    for the sampled conformations, evaluated on the trajectory frames with the
    RPY tensor (tr mu_ij / 3 = 1/(6 pi eta r_ij) for r >= 2a, (1 - r/4a)/(6 pi eta a) for
    overlapping beads).
  * Zimm scaling D ~ N^-nu with nu from the measured radius of gyration,
    R_g ~ N^nu (Flory nu ~ 0.588 for long self-avoiding chains).

    python3 examples/bd/polymer/plot.py [--out DIR] [--png FILE]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
import _analysis as an  # noqa: E402
from run import LENGTHS, METHODS, TOTAL_BEADS  # noqa: E402

D0 = 1 / (6 * np.pi)  # a = eta = kT = 1
LAGS = np.arange(1, 21)  # frames (t = 1 each)


def analyse(run: Path, n: int):
    """(D, dD, D_Kirkwood, R_g, lag times, msd, msd error) of one run of chains of n beads."""
    traj = an.Trajectory(run / "trajectory.xyz")
    x = traj.positions.reshape(len(traj.times), TOTAL_BEADS // n, n, 3)  # (frames, chains, beads, 3)
    com = x.mean(axis=2)
    m, dm = an.msd(com, LAGS)
    t = (traj.times[1] - traj.times[0]) * LAGS
    D, dD = m[0] / (6 * t[0]), dm[0] / (6 * t[0])
    sample = x[len(x) // 5 :: 25]  # conformations after 20 % of the run
    dk, rg = [], []
    for conf in sample.reshape(-1, n, 3):
        r = np.linalg.norm(conf[:, None] - conf[None], axis=-1)
        f, g = an.rpy_pair(np.where(r > 0, r, 1.0), 1.0, 1.0)
        tr3 = np.where(r > 0, f + g / 3, D0)
        dk.append(tr3.sum() / n**2)
        rg.append(np.mean(np.sum((conf - conf.mean(0)) ** 2, axis=1)))
    return D, dD, np.mean(dk), np.sqrt(np.mean(rg)), t, m, dm


def main() -> int:
    args = an.script_args(__doc__, HERE, "polymer.png")
    _, fig, (ax1, ax2) = an.figure(1, 2, figsize=(11, 4.3))
    res = {}
    print(f"{'run':8} {'D/D0':>16} {'N D/D0':>7} {'Kirkwood/D0':>11} {'D/D_K':>6} {'R_g/a':>6}")
    for tag in METHODS:
        for n in LENGTHS:
            D, dD, dk, rg, t, m, dm = analyse(args.out / f"{tag}_n{n}", n)
            res[tag, n] = (D, dD, dk, rg)
            ref = D0 / n if tag == "fd" else dk
            print(f"{tag}_n{n:<5} {D / D0:9.4f} ± {dD / D0:.4f} {n * D / D0:7.3f} {dk / D0:11.4f} "
                  f"{D / ref:6.3f} {rg:6.2f}" + ("  (D/D0N)" if tag == "fd" else ""))
            if n in (8, 64):
                ax2.errorbar(t, m / (6 * t) / D0, dm / (6 * t) / D0, fmt=".-" if tag == "hi" else ".--", ms=3,
                             label=f"N={n} " + ("RPY" if tag == "hi" else "free draining"))
    ns = np.array(LENGTHS, float)
    fits = {}
    for tag, label, mk in (("hi", "BD with RPY (Zimm)", "o"), ("fd", "BD free draining (Rouse)", "s")):
        D, dD, dk, rg = map(np.array, zip(*(res[tag, n] for n in LENGTHS)))
        fits[tag] = an.power_fit(ns, D, dD)
        ax1.errorbar(ns, D / D0, dD / D0, fmt=mk, label=f"{label}: D ~ N^-{-fits[tag][0]:.3f}±{fits[tag][1]:.3f}")
    D, dD, dk, rg = map(np.array, zip(*(res["hi", n] for n in LENGTHS)))
    nu, dnu, _ = an.power_fit(ns, rg)
    big = ns >= 16
    p_tail = an.power_fit(ns[big], D[big], dD[big])
    ax1.plot(ns, 1 / ns, "k--", lw=1, label=r"Rouse $D_0/N$")
    ax1.plot(ns, dk / D0, "C0:", lw=1.5, label=r"Kirkwood $\frac{kT}{N^2}\sum_{ij}\langle\mathrm{tr}\,\mu_{ij}\rangle/3$")
    ax1.plot(ns, dk[-1] / D0 * (ns / ns[-1]) ** (-nu), "C2-", lw=0.8, label=rf"$N^{{-\nu}}$, $\nu$ = {nu:.2f} from $R_g$")
    ax1.set(xscale="log", yscale="log", xlabel="beads per chain N", ylabel=r"$D/D_0$",
            title="centre-of-mass diffusion of bead-spring chains")
    ax1.set_xticks(LENGTHS, [str(n) for n in LENGTHS])
    ax1.minorticks_off()
    ax1.legend(fontsize=7.5)
    ax2.set(xscale="log", yscale="log", xlabel="lag time t", ylabel=r"MSD$_{cm}/(6 t D_0)$",
            title="centre-of-mass MSD / 6t (flat: pure diffusion)")
    ax2.legend(fontsize=8)
    print(f"exponents: free draining D ~ N^-{-fits['fd'][0]:.3f} ± {fits['fd'][1]:.3f}; "
          f"RPY D ~ N^-{-fits['hi'][0]:.3f} ± {fits['hi'][1]:.3f} (N >= 16: N^-{-p_tail[0]:.3f} ± {p_tail[1]:.3f}); "
          f"R_g ~ N^{nu:.3f} ± {dnu:.3f}")
    return an.save_figure(fig, args.png)


if __name__ == "__main__":
    sys.exit(main())
