#!/usr/bin/env python3
"""Diffusion of a large particle carrying adsorbed small ones, free draining
against RPY hydrodynamics, from the runs of run.py: D_eff(t) = MSD(t)/(6t) of
the large particles, over D0 = kT/(6 pi eta a_L).

Long-time limits of a bound complex (large + n small), drawn as lines:
  * free draining: the friction-weighted centre sum_i zeta_i x_i / sum_i zeta_i
    moves only by noise, so D = kT / sum_i zeta_i = D0 a_L / (a_L + n a_S)
    exactly (the "caging" artefact of Tran et al. (2015), section 4.1);
  * RPY: the rigid-complex estimate D = (kT/3) tr[(sum_ij (M^-1)_ij)^-1], the
    translational mobility of the complex frozen in its sampled shapes
    (M = the complex's RPY matrix; the same formula gives the free-draining
    value above with M diagonal);
  * free draining at short times, before the small ones slide along the
    surface: only the radial component of the large particle's motion drags
    them, D = D0 a_L / (a_L + n a_S / 3) (dotted).

    python3 examples/bd/bimodal/plot.py [--out DIR] [--png FILE]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
import _analysis as an  # noqa: E402
from run import CASES  # noqa: E402

A_L, A_S, COMPLEXES = 4.0, 1.0, 4
D0 = 1 / (6 * np.pi * A_L)


def rigid_complex(x: np.ndarray, radii: np.ndarray, hi: bool) -> float:
    """(kT/3) tr[(1^T M^-1 1)^-1] of one complex (positions x, radii), kT = eta = 1."""
    m = an.rpy_matrix(x, radii) if hi else np.diag(np.repeat(1 / (6 * np.pi * radii), 3))
    resistance = np.linalg.inv(m).reshape(len(x), 3, len(x), 3).sum(axis=(0, 2))
    return float(np.trace(np.linalg.inv(resistance)) / 3)


def analyse(run: Path, hi: bool):
    traj = an.Trajectory(run / "trajectory.xyz")
    large = np.nonzero(traj.species == "large")[0]
    dt = traj.times[1] - traj.times[0]
    lags = np.unique(np.round(np.logspace(0, np.log10(len(traj.times) // 5), 25)).astype(int))
    out = {"t": lags * dt}
    for key, idx in (("complex", large[:COMPLEXES]), ("bare", large[COMPLEXES:])):
        m, dm = an.msd(traj.positions[:, idx], lags)
        out[key] = (m / (6 * lags * dt) / D0, dm / (6 * lags * dt) / D0)
    # members of each complex: the large particle and the small ones listed after it
    bounds = list(large[:COMPLEXES]) + [large[COMPLEXES]]
    est, bound = [], []
    for f in range(len(traj.times) // 10, len(traj.times), max(1, len(traj.times) // 20)):
        for c in range(COMPLEXES):
            sl = slice(bounds[c], bounds[c + 1])
            x = traj.positions[f, sl]
            est.append(rigid_complex(x, traj.radii[sl], hi) / D0)
    x_end = traj.positions[-1]
    for c in range(COMPLEXES):
        r = np.linalg.norm(x_end[bounds[c] + 1 : bounds[c + 1]] - x_end[bounds[c]], axis=1)
        bound.append(np.sum(r < 1.1 * (A_L + A_S)))
    out["rigid"] = (np.mean(est), np.std(est))
    out["bound"] = bound
    out["n_small"] = bounds[1] - bounds[0] - 1
    return out


def main() -> int:
    args = an.script_args(__doc__, HERE, "bimodal.png")
    _, fig, ax = an.figure(figsize=(10, 4.6))
    for name, color in zip(CASES, ("C3", "C0")):
        hi = CASES[name] != "none"
        r = analyse(args.out / name, hi)
        label = "RPY hydrodynamics" if hi else "free draining"
        t = r["t"]
        y, dy = r["complex"]
        ax.errorbar(t, y, dy, fmt="o-", color=color, ms=3, label=f"{label}: large + {r['n_small']} small")
        yb, dyb = r["bare"]
        ax.errorbar(t, yb, dyb, fmt="x:", color=color, ms=4, lw=0.8, label=f"{label}: bare large")
        ax.axhline(r["rigid"][0], color=color, ls="--", lw=1,
                   label=f"{label}: rigid-complex limit {r['rigid'][0]:.3f}")
        if not hi:
            radial = A_L / (A_L + r["n_small"] * A_S / 3)
            ax.axhline(radial, color=color, ls=":", lw=1, label=f"{label}: radial drag only {radial:.3f}")
        print(f"{name}: large + {r['n_small']} small: D/D0 = {y[0]:.3f} ± {dy[0]:.3f} at t = {t[0]:g}, "
              f"{y[-1]:.3f} ± {dy[-1]:.3f} at t = {t[-1]:g}; rigid-complex limit {r['rigid'][0]:.3f} "
              f"(spread over frames {r['rigid'][1]:.3f}); bare large D/D0 = {yb[0]:.3f} ± {dyb[0]:.3f} at t = {t[0]:g}; "
              f"small still adsorbed at the end: {[int(b) for b in r['bound']]} of {r['n_small']}")
    ax.axhline(1, color="gray", lw=0.8)
    ax.set(xscale="log", xlabel=r"lag time $t$ [$\eta a_S^3/kT$]", ylabel=r"$\mathrm{MSD}(t)/(6 t D_0)$ of the large particle",
           ylim=(0, 1.25), title=r"large ($a_L=4$) with 20 adsorbed small ($a_S=1$): caging")
    ax.legend(fontsize=7.5, loc="center left", bbox_to_anchor=(1.01, 0.5))
    return an.save_figure(fig, args.png)


if __name__ == "__main__":
    sys.exit(main())
