#!/usr/bin/env python3
"""Aggregation of silica-covered alumina particles (alumina_silica.toml: the
36-18 adsorption well; see the README for why not the DLVO config), by three
methods from one initial state and noise seed, and the number of alumina
clusters against time, with the aluminas' diffusion coefficient from their mean-squared
displacement, as a plot (aggregation.png):

* naive: free draining, alumina by Langevin dynamics, silica by Brownian
  dynamics (the paper's eqs. 3-5): each alumina drags its adsorbed silica's
  friction (the caging artefact);
* sac: the same with the SAC scheme (the paper's Algorithm 2);
* rpy: every particle Brownian with RPY hydrodynamic interactions
  (mobility.method = "direct"; the integrator refuses Langevin types and SAC
  with HI), the reference by which HI removes the caging.

Initial state (make_state): --aluminas aluminas at random in a sphere at
alumina volume fraction --phi, surface gaps between aluminas at least --gap nm,
each carrying --silica silica at contact (the 36-18 well's minimum), spread by
a Fibonacci lattice turned at random per alumina. Open geometry (the HI
methods for unequal radii, direct and fmm, are open-boundary), no confinement.

Time step (--dt): 5e-9 s, ten times the paper's 5e-10 s, so that the
aluminas aggregate within the run: an adsorbed silica relaxes in the well in
gamma_S / V'' = 2.9e-7 s = 58 steps, its random step (0.4 nm) is a fifth of the
well's thermal width, and the alumina's m / gamma = 7 dt, which the GJF
Langevin step integrates at any dt (docs/theory/bd.md Sec. 8).

Clusters (the paper's Sec. 2.1 and 4.3, counting alumina only): particles are
linked when their centres are closer than 1.05 (a_i + a_j), the adsorption
radius R_A of the SAC scheme; a cluster is a connected group holding at least
one alumina (a single alumina is a cluster of one), linked directly or through
adsorbed silica. The plot shows their number against time: --aluminas at the
start, falling as the aluminas aggregate.

    OMP_NUM_THREADS=2 python3 examples/bd/alumina_silica/aggregation.py [--steps N] [--rpy_steps N]
    python3 examples/bd/alumina_silica/aggregation.py --only     # the plot alone, from the runs in --out
"""

from __future__ import annotations

import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
import _analysis as an  # noqa: E402

BASE = HERE / "alumina_silica.toml"
A_ALUMINA, A_SILICA = 200.0, 12.5
GAP_AS = 0.0  # nm, the alumina-silica minimum of alumina_silica.toml's 36-18 well
LINK = 1.05  # centre distance / (a_i + a_j) that links two particles (the adsorption radius)
TIME_UNIT = 2.47201e-10  # s (eta nm^3 / kT at 293 K)
CASES = {  # name: (scheme, alumina dynamics, mobility method, label)
    "naive": ("naive", "langevin", "none", "naive (free draining, Langevin alumina)"),
    "sac": ("sac", "langevin", "none", "SAC (Algorithm 2)"),
    "rpy": ("naive", "brownian", "direct", "RPY hydrodynamic interactions (all Brownian)"),
}


def fibonacci_sphere(n: int) -> np.ndarray:
    k = np.arange(n)
    z = 1.0 - (2.0 * k + 1.0) / n
    rho = np.sqrt(1.0 - z * z)
    phi = math.pi * (3.0 - math.sqrt(5.0)) * k
    return np.stack([rho * np.cos(phi), rho * np.sin(phi), z], axis=1)


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.diag(r))


def make_state(path: Path, aluminas: int, silica: int, phi: float, gap: float, seed: int) -> None:
    """Writes the particle file: aluminas by random sequential addition in a sphere, silica on them."""
    rng = np.random.default_rng(seed)
    radius = A_ALUMINA * (aluminas / phi) ** (1.0 / 3.0)  # centres in a sphere of n a^3 / phi
    centres: list[np.ndarray] = []
    for _ in range(1000000):
        x = rng.uniform(-radius, radius, 3)
        if np.linalg.norm(x) <= radius and all(np.linalg.norm(x - c) >= 2 * A_ALUMINA + gap for c in centres):
            centres.append(x)
            if len(centres) == aluminas:
                break
    else:
        sys.exit(f"error: {aluminas} aluminas with gaps >= {gap} nm do not fit at phi = {phi}: lower --phi")
    shell = fibonacci_sphere(silica) * (A_ALUMINA + A_SILICA + GAP_AS)
    rows = [f"# {aluminas} alumina (a = {A_ALUMINA:g} nm) at volume fraction {phi:g} in a sphere, gaps >= {gap:g} nm, "
            f"each with {silica} silica (a = {A_SILICA:g} nm) at h = {GAP_AS:g} nm; x y z type (nm)"]
    rows += [f"{c[0]:.6f} {c[1]:.6f} {c[2]:.6f} alumina" for c in centres]
    for c in centres:
        for s in shell @ random_rotation(rng).T + c:
            rows.append(f"{s[0]:.6f} {s[1]:.6f} {s[2]:.6f} silica")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(rows) + "\n")


def aggregates(traj: an.Trajectory) -> tuple[np.ndarray, np.ndarray]:
    """Per frame, the number of clusters of aluminas (connected groups holding at least one
    alumina: single aluminas count as clusters of one) and of aggregates (groups with >= 2)."""
    alumina = traj.species == "alumina"
    clusters, multi = [], []
    for x in traj.positions:
        labels = an.clusters(x, traj.radii, LINK)
        per_cluster = np.bincount(labels[alumina], minlength=labels.max() + 1)
        clusters.append(int(np.sum(per_cluster >= 1)))
        multi.append(int(np.sum(per_cluster >= 2)))
    return np.array(clusters), np.array(multi)


def alumina_diffusion(traj: an.Trajectory, lags_us: list[float]) -> tuple[np.ndarray, np.ndarray]:
    """D / D0 of the aluminas from their mean-squared displacement over each lag (all frame pairs,
    all aluminas), with a standard error from the number of independent windows:
    D sqrt(2 / (3 windows)). Lags >> m / gamma = 3.5e-8 s, so no inertia correction."""
    x = traj.positions[:, traj.species == "alumina"]
    step = traj.times[1] - traj.times[0]
    d0 = 1.0 / (6.0 * math.pi * A_ALUMINA)  # kT / (6 pi eta a), kT = eta = 1
    values, errors = [], []
    for lag in lags_us:
        k = max(1, int(round(lag * 1e-6 / TIME_UNIT / step)))
        d = np.sum((x[k:] - x[:-k]) ** 2, axis=2).mean() / (6.0 * k * step) / d0
        windows = max(1, (len(x) - 1) // k) * x.shape[1]
        values.append(d)
        errors.append(d * math.sqrt(2.0 / (3.0 * windows)))
    return np.array(values), np.array(errors)


def main() -> int:
    args = an.script_args(
        __doc__, HERE,
        steps=dict(type=int, default=200000, help="steps of the free-draining runs (default: %(default)s)"),
        rpy_steps=dict(type=int, default=50000, help="steps of the RPY run (default: %(default)s)"),
        aluminas=dict(type=int, default=27, help="aluminas (default: %(default)s)"),
        silica=dict(type=int, default=15, help="silica per alumina (default: %(default)s)"),
        phi=dict(type=float, default=0.35, help="alumina volume fraction of the sphere (default: %(default)s)"),
        gap=dict(type=float, default=45.0, help="smallest alumina-alumina gap, nm (default: %(default)s)"),
        dt=dict(type=float, default=20.226,
                help="time step, time units of 2.472e-10 s (default: %(default)s = 5e-9 s)"),
        frames=dict(type=int, default=200, help="frames per run (default: %(default)s)"),
        only=dict(nargs="*", default=list(CASES), help="cases to run (default: all)"),
        plot=dict(type=Path, default=HERE / "aggregation.png", help="plot file (default: %(default)s)"))
    particles = args.out / "particles.txt"
    make_state(particles, args.aluminas, args.silica, args.phi, args.gap, seed=3)
    for name in args.only:
        scheme, dynamics, method, _ = CASES[name]
        steps = args.rpy_steps if method != "none" else args.steps
        cfg = an.derive_config(BASE, args.out / f"{name}.toml", {
            "particles.file": str(particles), "integrator.scheme": scheme, "integrator.steps": steps,
            "integrator.dt": args.dt,
            "types.dynamics": dynamics, "mobility.method": method,
            "output.trajectory_every": max(1, steps // args.frames), "output.log_every": max(1, steps // 20),
            "output.checkpoint_every": steps})
        if dynamics == "brownian":  # a Brownian type takes no density
            cfg.write_text("".join(l for l in cfg.read_text().splitlines(True) if not l.startswith("density")))
        start = time.perf_counter()
        try:
            an.run_bd(cfg, args.out / name, threads=args.threads)
        except subprocess.CalledProcessError:  # rpyfmm said why; its trajectory up to there is kept
            print(f"  {name}: stopped before step {steps}; plotting its trajectory up to there")
        seconds = time.perf_counter() - start
        print(f"  {name}: {seconds:.0f} s ({1e3 * seconds / steps:.3f} ms per step of the {steps} asked for)")
    plt, fig, (ax, bx) = an.figure(1, 2, figsize=(12, 4.2))
    lags = [2.5, 5.0, 10.0, 20.0]  # us
    for name, (_, _, _, label) in CASES.items():
        path = args.out / name / "trajectory.xyz"
        if not path.is_file():
            continue
        traj = an.Trajectory(path)
        counts, multi = aggregates(traj)
        print(f"{name}: alumina clusters {counts[0]} at t = 0, {counts[len(counts) // 2]} at "
              f"t = {traj.times[len(counts) // 2] * TIME_UNIT * 1e3:.3f} ms, {counts[-1]} at "
              f"t = {traj.times[-1] * TIME_UNIT * 1e3:.3f} ms; aggregates (>= 2) {multi[-1]} at the end")
        ax.step(traj.times * TIME_UNIT * 1e3, counts, where="post", label=label)
        d, err = alumina_diffusion(traj, lags)
        print(f"{name}: alumina D / D0 at lags {lags} us: " + ", ".join(f"{v:.3f} ± {e:.3f}" for v, e in zip(d, err)))
        bx.errorbar(lags, d, yerr=err, marker="o", capsize=3, label=label)
    ax.set_xlabel("time (ms)")
    ax.set_ylabel("alumina clusters (single aluminas included)")
    ax.set_title(f"{args.aluminas} alumina + {args.aluminas * args.silica} silica, phi = {args.phi:g}, "
                 f"dt = {args.dt * TIME_UNIT:.2g} s")
    ax.legend()
    gamma_ratio = A_SILICA / A_ALUMINA * args.silica
    for value, text in ((1.0, "free alumina"), (1.0 / (1.0 + gamma_ratio / 3.0), "radial drag"),
                        (1.0 / (1.0 + gamma_ratio), "kT / sum gamma")):
        bx.axhline(value, color="grey", lw=0.8, ls=":")
        bx.text(lags[-1] * 1.05, value, text, va="center", fontsize=8)
    bx.set_xscale("log")
    bx.set_xlabel("lag (us)")
    bx.set_ylabel("alumina D / D0 (MSD / 6 D0 t)")
    bx.set_title("alumina mobility: caged by free draining only")
    return an.save_figure(fig, args.plot)


if __name__ == "__main__":
    sys.exit(main())
