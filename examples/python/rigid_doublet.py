#!/usr/bin/env python3
"""Rigid bodies of beads from Python: two spheres settling side by side.

Each sphere (radius R = 1) is a bead shell: `rpyfmm.icosphere_beads(s)` puts 10 4^s + 2
touching beads of radius a on it. `rpyfmm.RigidBodies` solves for the velocities of both rigid
shells under equal forces along z. Every bead interacts with every other through the RPY
mobility (DirectRpy here; FmmRpy or PseRpy work the same way).

For two touching spheres moving along their line of centres, Stokes flow gives an exact
answer: the pair settles 1 / 0.6451 = 1.550 times faster than one sphere (Stimson & Jeffery
1926, contact limit). The shells approach it as the beads shrink. The script extrapolates
linearly in a / R to zero bead size, like the classical shell-model extrapolation. It prints
the speed-up for centre distances 2R ... 4R along and across the line of centres.

    python3 examples/python/rigid_doublet.py            # shells of 42, 162, 642 beads (~5 s)
"""

from __future__ import annotations

import numpy as np

import rpyfmm

STIMSON_JEFFERY_CONTACT = 1.0 / 0.6451  # two touching spheres along their line of centres


def settling_speedups(subdivisions: int, distances: list[float]) -> tuple[float, dict]:
    shell = rpyfmm.icosphere_beads(subdivisions)  # unit sphere
    a = rpyfmm.icosphere_bead_radius(subdivisions)
    beads = rpyfmm.DirectRpy(viscosity=1.0)
    bodies = rpyfmm.RigidBodies(beads, tolerance=1e-10)
    bodies.set_configuration(shell, a, [0, len(shell)])
    single = bodies.apply(np.array([[0.0, 0.0, 1.0, 0.0, 0.0, 0.0]]))[0][0, 2]
    out = {}
    for d in distances:
        for name, axis in (("along", np.array([0.0, 0.0, 1.0])), ("across", np.array([1.0, 0.0, 0.0]))):
            x = np.vstack([shell - 0.5 * d * axis, shell + 0.5 * d * axis])
            bodies.set_configuration(x, a, [0, len(shell), 2 * len(shell)])
            uw, report = bodies.apply(np.array([[0, 0, 1.0, 0, 0, 0], [0, 0, 1.0, 0, 0, 0]]))
            out[(d, name)] = uw[0, 2] / single
    return a, out


def main() -> None:
    distances = [2.0, 2.5, 3.0, 4.0]
    rows = [settling_speedups(s, distances) for s in (1, 2, 3)]
    print("speed-up of a settling pair over one sphere (centre distance d, sphere radius 1)")
    print(f"{'beads':>6} {'a/R':>7} " + " ".join(f"{f'd={d} along':>12} {f'd={d} across':>12}" for d in distances))
    for s, (a, out) in zip((1, 2, 3), rows):
        print(f"{10 * 4**s + 2:>6} {a:7.4f} " + " ".join(f"{out[(d, 'along')]:12.4f} {out[(d, 'across')]:12.4f}"
                                                        for d in distances))
    (a1, o1), (a2, o2) = rows[1], rows[2]
    extrapolate = {k: o2[k] - (o2[k] - o1[k]) / (a2 - a1) * a2 for k in o2}
    print(f"{'a -> 0':>6} {0.0:7.4f} " + " ".join(f"{extrapolate[(d, 'along')]:12.4f} {extrapolate[(d, 'across')]:12.4f}"
                                                 for d in distances))
    contact = extrapolate[(2.0, "along")]
    print(f"touching, along the line of centres: {contact:.4f}; Stimson & Jeffery: {STIMSON_JEFFERY_CONTACT:.4f} "
          f"({100 * (contact / STIMSON_JEFFERY_CONTACT - 1):+.2f}%)")


if __name__ == "__main__":
    main()
