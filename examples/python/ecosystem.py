#!/usr/bin/env python3
"""rpyfmm with the HOOMD-blue tool chain: a Brownian-dynamics run writes a GSD trajectory, the gsd
package reads it back, and freud (or NumPy where freud is not installed) computes the radial
distribution function g(r) and the mean squared displacement (MSD); matplotlib plots both.

N spheres (radius a = 1) at volume fraction phi in a periodic box, WCA repulsion, RPY
hydrodynamics by Positively Split Ewald (`method = "pse"`), Brownian noise. Units: a = 1, kT = 1,
eta = 1, so D0 = kT / (6 pi eta a) = 1 / (6 pi).

    pip install gsd freud-analysis matplotlib          # gsd is needed; freud and matplotlib optional
    python3 examples/python/ecosystem.py               # 500 spheres, 600 steps (~6 s on 2 cores)
    python3 examples/python/ecosystem.py --n 2000 --steps 2000 --out run2000

The same trajectory opens in OVITO and VMD (gsd plugin), and in MDAnalysis as
`MDAnalysis.Universe("<out>/bd/trajectory.gsd")`. Positions are wrapped into HOOMD's
origin-centred box, and `particles/image` unwraps them (docs/bd-config.md, "GSD trajectories").
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

# Idle OpenMP threads sleep instead of spinning (read when libgomp loads, before `import rpyfmm`):
# on a busy machine spinning threads slow a run several times over.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import numpy as np  # noqa: E402

import rpyfmm  # noqa: E402

CONFIG = """
[system]
geometry = "periodic"
box = [{L}, {L}, {L}]
[[types]]
name = "sphere"
radius = 1.0
[particles]
source = "random"
count = {n}
seed = {seed}
[[pair]]
types = ["sphere", "sphere"]
kind = "wca"
[integrator]
dt = {dt}
steps = {steps}
seed = {seed}
[mobility]
method = "{mobility}"
tolerance = 1e-3
[output]
dir = "{out}"
format = "gsd"
trajectory_every = {every}
log_every = {every}
"""


def read_gsd(path: Path):
    """Positions (F, N, 3), images (F, N, 3), the box and the frames' times from a GSD file."""
    import gsd.hoomd

    with gsd.hoomd.open(str(path), "r") as trajectory:
        frames = list(trajectory)
    positions = np.stack([f.particles.position for f in frames])
    images = np.stack([f.particles.image for f in frames])
    times = np.array([f.log["bd/time"][0] for f in frames])
    return positions, images, frames[0].configuration.box, times


def rdf_numpy(positions: np.ndarray, L: float, r_max: float, bins: int):
    """g(r) over frames by minimum-image pair distances (i < j), normalized by the ideal gas."""
    n = positions.shape[1]
    edges = np.linspace(0.0, r_max, bins + 1)
    counts = np.zeros(bins)
    i, j = np.triu_indices(n, 1)
    for x in positions.astype(np.float64):
        d = x[i] - x[j]
        d -= L * np.round(d / L)
        counts += np.histogram(np.linalg.norm(d, axis=1), bins=edges)[0]
    shell = 4.0 / 3.0 * math.pi * (edges[1:] ** 3 - edges[:-1] ** 3)
    ideal = len(positions) * len(i) * shell / L**3
    return 0.5 * (edges[1:] + edges[:-1]), counts / ideal


def msd_numpy(unwrapped: np.ndarray) -> np.ndarray:
    """MSD at every frame lag, averaged over particles and time origins (window average)."""
    frames = len(unwrapped)
    out = np.zeros(frames)
    for lag in range(1, frames):
        out[lag] = np.mean(np.sum((unwrapped[lag:] - unwrapped[:-lag]) ** 2, axis=2))
    return out


def analyse(positions, images, box, r_max: float, bins: int):
    """(r, g(r), MSD per lag, the name of the library that computed them)."""
    L = float(box[0])
    try:
        import freud
    except ImportError:
        r, g = rdf_numpy(positions, L, r_max, bins)
        return r, g, msd_numpy(positions + images * L), "numpy (freud is not installed)"
    fbox = freud.box.Box.from_box(box)
    rdf = freud.density.RDF(bins=bins, r_max=r_max)
    for x in positions:
        rdf.compute(system=(fbox, x), reset=False)
    msd = freud.msd.MSD(fbox, mode="window").compute(positions, images).msd
    return rdf.bin_centers, rdf.rdf, msd, f"freud {freud.__version__}"


def plot(out: Path, r, g, lag_times, msd, d0: float) -> None:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed: no plot (pip install matplotlib)")
        return
    fig, (left, right) = plt.subplots(1, 2, figsize=(9, 3.6))
    left.plot(r, g)
    left.axhline(1.0, color="grey", lw=0.5)
    left.set(xlabel="r / a", ylabel="g(r)", title="radial distribution")
    right.plot(lag_times, msd, "o-", ms=3, label="MSD from the GSD trajectory")
    right.plot(lag_times, 6 * d0 * lag_times, "--", label="6 D0 t")
    right.set(xlabel="t", ylabel="MSD / a^2", title="mean squared displacement")
    right.legend()
    fig.tight_layout()
    fig.savefig(out / "ecosystem.png", dpi=120)
    print(f"plot: {out / 'ecosystem.png'}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--n", type=int, default=500, help="number of spheres")
    parser.add_argument("--phi", type=float, default=0.15, help="volume fraction")
    parser.add_argument("--steps", type=int, default=600)
    parser.add_argument("--dt", type=float, default=0.02, help="time step (units eta a^3 / kT)")
    parser.add_argument("--every", type=int, default=5, help="a GSD frame every this many steps")
    parser.add_argument("--mobility", default="pse", help="pse (periodic RPY) or none (free draining)")
    parser.add_argument("--seed", type=int, default=3)
    parser.add_argument("--out", default="ecosystem-out", help="directory for the run and the plot")
    args = parser.parse_args()
    try:
        import gsd.hoomd  # noqa: F401
    except ImportError:
        print("this example reads the trajectory with the gsd package: pip install gsd", file=sys.stderr)
        return 1

    out = Path(args.out)
    L = (args.n * 4.0 / 3.0 * math.pi / args.phi) ** (1.0 / 3.0)
    config = CONFIG.format(L=L, n=args.n, seed=args.seed, dt=args.dt, steps=args.steps, mobility=args.mobility,
                           out=(out / "bd").as_posix(), every=args.every)
    start = time.perf_counter()
    summary = rpyfmm.run_bd(config)
    print(f"BD: {args.n} spheres, {args.steps} steps with {summary['mobility']} in "
          f"{time.perf_counter() - start:.1f} s -> {summary['trajectory']}")

    positions, images, box, times = read_gsd(Path(summary["trajectory"]))
    print(f"{len(positions)} frames read with gsd: box {box[:3]}, positions in [-L/2, L/2) with images")
    r, g, msd, library = analyse(positions, images, box, r_max=min(6.0, L / 2), bins=60)
    lag_times = times - times[0]
    d0 = 1.0 / (6.0 * math.pi)
    slope = np.polyfit(lag_times[1:], msd[1:], 1)[0] if len(msd) > 2 else float("nan")
    print(f"g(r) and MSD by {library}: g(r) peaks at r = {r[np.argmax(g)]:.2f} a (contact 2 a); "
          f"D_eff / D0 = {slope / (6 * d0):.3f}")
    plot(out, r, g, lag_times, msd, d0)
    return 0


if __name__ == "__main__":
    sys.exit(main())
