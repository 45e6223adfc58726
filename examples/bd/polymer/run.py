#!/usr/bin/env python3
"""Chains of N = 4, 8, 16, 32, 64 beads (256 beads per run: 256/N chains),
with RPY hydrodynamics (Zimm) and free draining (Rouse), derived from
chains.toml (only chains, beads, mobility.method and the output change).

    OMP_NUM_THREADS=1 python3 examples/bd/polymer/run.py [--out DIR]
    python3 examples/bd/polymer/plot.py [--out DIR]
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
import _analysis as an  # noqa: E402

BASE = HERE / "chains.toml"
TOTAL_BEADS = 256
LENGTHS = [4, 8, 16, 32, 64]
METHODS = {"hi": "direct", "fd": "none"}


def main() -> int:
    args = an.script_args(__doc__, HERE)
    total = 0.0
    for tag, method in METHODS.items():
        for n in LENGTHS:
            name = f"{tag}_n{n}"
            cfg = an.derive_config(BASE, args.out / f"{name}.toml", {
                "particles.chains": TOTAL_BEADS // n, "particles.beads": n, "mobility.method": method})
            total += an.run_bd(cfg, args.out / name, threads=args.threads)
    print(f"done in {total:.0f} s; now: python3 {HERE / 'plot.py'} --out {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
