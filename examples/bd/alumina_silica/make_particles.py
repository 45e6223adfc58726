#!/usr/bin/env python3
"""Initial configuration of the alumina-silica example (particles.txt): one
alumina (a = 200 nm) at the origin with 82 silica (a = 12.5 nm) adsorbed at
surface gap --gap (default 0: contact, r = a_A + a_S = 212.5 nm; the DLVO config
alumina_silica_dlvo.toml takes its primary minimum, --gap 3.16 --out
particles_dlvo.txt), spread evenly over its surface (a
Fibonacci lattice: deterministic, nearest silica ~80 nm apart). 82 silica per
alumina is the composition R = 1.1 % of Tran et al. (2015) (Annex 2, Table 5).

    python3 examples/bd/alumina_silica/make_particles.py [--silica 82] [--gap 0] [--out particles.txt]
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
A_ALUMINA, A_SILICA = 200.0, 12.5


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--silica", type=int, default=82, help="adsorbed silica (default: %(default)s)")
    p.add_argument("--gap", type=float, default=0.0, help="surface gap in nm (default: %(default)s)")
    p.add_argument("--out", type=Path, default=HERE / "particles.txt")
    args = p.parse_args()
    r = A_ALUMINA + A_SILICA + args.gap
    rows = [f"# alumina-silica example: 1 alumina (a = {A_ALUMINA:g} nm) with {args.silica} silica "
            f"(a = {A_SILICA:g} nm) at r = {r:g} nm; x y z type (nm)",
            "0.000000 0.000000 0.000000 alumina"]
    golden = math.pi * (3.0 - math.sqrt(5.0))
    for k in range(args.silica):
        z = 1.0 - (2.0 * k + 1.0) / args.silica
        rho = math.sqrt(1.0 - z * z)
        rows.append("{:.6f} {:.6f} {:.6f} silica".format(r * rho * math.cos(golden * k), r * rho * math.sin(golden * k),
                                                          r * z))
    args.out.write_text("\n".join(rows) + "\n")
    print(f"wrote {args.out} ({args.silica + 1} particles)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
