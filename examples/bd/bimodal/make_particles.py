#!/usr/bin/env python3
"""Initial configuration of the bimodal example (particles.txt): 4 "large"
particles (radius 4), each with 20 "small" ones (radius 1) adsorbed at the
minimum of the 36-18 well, r = 2^(1/18) (a_L + a_S), at random non-overlapping
spots, plus 2 bare large particles (the D0 reference); all 50 a apart.

    python3 examples/bd/bimodal/make_particles.py [--small 20] [--out particles.txt]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
A_LARGE, A_SMALL, SPACING = 4.0, 1.0, 50.0
COMPLEXES, BARE = 4, 2


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--small", type=int, default=20, help="small particles per complex")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--out", type=Path, default=HERE / "particles.txt")
    args = p.parse_args()
    rng = np.random.default_rng(args.seed)
    r_ads = 2 ** (1 / 18) * (A_LARGE + A_SMALL)
    rows = [f"# bimodal example: {COMPLEXES} large (a = {A_LARGE:g}) with {args.small} small (a = {A_SMALL:g}) "
            f"adsorbed at r = {r_ads:.4f}, {BARE} bare large; x y z type"]
    for c in range(COMPLEXES + BARE):
        centre = np.array([c * SPACING, 0.0, 0.0])
        rows.append("{:.6f} {:.6f} {:.6f} large".format(*centre))
        if c >= COMPLEXES:
            continue
        placed = []
        while len(placed) < args.small:  # random sequential adsorption on the sphere, gap 5 %
            u = rng.normal(size=3)
            q = r_ads * u / np.linalg.norm(u)
            if all(np.linalg.norm(q - s) > 2.1 * A_SMALL for s in placed):
                placed.append(q)
        rows += ["{:.6f} {:.6f} {:.6f} small".format(*(centre + q)) for q in placed]
    args.out.write_text("\n".join(rows) + "\n")
    print(f"wrote {args.out}: {COMPLEXES + BARE + COMPLEXES * args.small} particles")
    return 0


if __name__ == "__main__":
    sys.exit(main())
