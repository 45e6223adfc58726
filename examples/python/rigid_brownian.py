#!/usr/bin/env python3
"""Brownian dynamics of rigid bodies from Python: rotational and translational diffusion of
bead-shell spheres, against their grand diffusion tensor.

Four spheres (radius 1, 42 beads each) sit 12 apart in free space, tracked at their centres.
`rpyfmm.RigidBodyDynamics` moves them with Brownian noise (a random slip on the beads, with
hydrodynamic interactions among all 168 beads) and the thermal drift kT d/dQ . N by a random
finite difference. The script measures

* the orientation correlation <u(t) . u(0)> of a body axis, which decays as exp(-2 D_r t), and
* the mean-square displacement of the centres, 6 D_t t,

and compares D_r and D_t with kT times the rotational and translational entries of the body
mobility N (`RigidBodies.mobility_matrix`, one sphere). The spheres' mutual hydrodynamic
coupling at distance 12 changes their self-diffusion by well under 1%; the statistical error
of the estimates is a few percent (printed).

    python3 examples/python/rigid_brownian.py           # ~30 s on one core
"""

from __future__ import annotations

import time

import numpy as np

import rpyfmm


def rotation_axis(quaternions: np.ndarray, axis: int = 2) -> np.ndarray:
    """Column `axis` of each body's rotation matrix (the body's z axis in the lab frame)."""
    w, x, y, z = quaternions.T
    return np.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], axis=1)


def main() -> None:
    kT, radius, spacing = 1.0, 1.0, 12.0
    shell = radius * rpyfmm.icosphere_beads(1)
    a = radius * rpyfmm.icosphere_bead_radius(1)
    centres = spacing * np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    m = len(centres)

    # Grand diffusion tensor of one sphere: kT N.
    single = rpyfmm.RigidBodies(rpyfmm.DirectRpy(), tolerance=1e-10)
    single.set_configuration(shell, a, [0, len(shell)])
    n = single.mobility_matrix()
    d_t, d_r = kT * n[0, 0], kT * n[3, 3]

    beads = rpyfmm.DirectRpy()
    offsets = [len(shell) * k for k in range(m + 1)]
    dt = 1.0 / (2 * d_r) / 200  # 200 steps per rotational relaxation time
    sim = rpyfmm.RigidBodyDynamics(beads, np.tile(shell, (m, 1)), a, offsets, centres, dt=dt, kT=kT, seed=2026)
    steps, stride = 12000, 10
    axes, positions = [rotation_axis(sim.orientations)], [sim.positions]
    start = time.perf_counter()
    for _ in range(steps // stride):
        sim.run(stride)
        axes.append(rotation_axis(sim.orientations))
        positions.append(sim.positions)
    seconds = time.perf_counter() - start
    axes, positions = np.array(axes), np.array(positions)  # (frames, m, 3)

    print(f"{m} spheres x {len(shell)} beads, {steps} steps of dt = {dt:.4g} in {seconds:.1f} s "
          f"({1e3 * seconds / steps:.1f} ms per step)")
    t = sim.totals
    print(f"per step: {t['solve_iterations'] / steps:.1f} GMRES iterations (velocities), "
          f"{t['drift_iterations'] / steps:.1f} (drift), {t['sqrt_iterations'] / steps:.1f} (bead noise)")
    print(f"grand diffusion tensor: D_t = {d_t:.5f}, D_r = {d_r:.5f}")
    print(f"{'lag t':>8} {'<u(t).u(0)>':>12} {'exp(-2 D_r t)':>14} {'MSD/(6 t)':>10}")
    lags = [2, 5, 10, 20]  # frames (the rotational time 1 / (2 D_r) is 20)
    for lag in lags:
        corr = np.einsum("fmc,fmc->fm", axes[lag:], axes[:-lag])
        msd = np.sum((positions[lag:] - positions[:-lag]) ** 2, axis=2)
        tau = lag * stride * dt
        print(f"{tau:8.2f} {corr.mean():12.4f} {np.exp(-2 * d_r * tau):14.4f} {msd.mean() / (6 * tau):10.5f}")
    # Block estimates (one per body) for the statistical error.
    lag = 10
    tau = lag * stride * dt
    per_body_r = -np.log(np.einsum("fmc,fmc->fm", axes[lag:], axes[:-lag]).mean(axis=0)) / (2 * tau)
    per_body_t = (np.sum((positions[lag:] - positions[:-lag]) ** 2, axis=2)).mean(axis=0) / (6 * tau)
    print(f"D_r measured {per_body_r.mean():.5f} +- {per_body_r.std(ddof=1) / np.sqrt(m):.5f} "
          f"(exact {d_r:.5f});  D_t measured {per_body_t.mean():.5f} +- "
          f"{per_body_t.std(ddof=1) / np.sqrt(m):.5f} (exact {d_t:.5f})")


if __name__ == "__main__":
    main()
