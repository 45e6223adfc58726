#!/usr/bin/env python3
"""Sedimenting clouds of N = 250 ... 2000 spheres with RPY hydrodynamics,
plus one free-draining cloud: derived from examples/bd/sedimentation.toml
(only particles.count, mobility.method and the output folder change).

    python3 examples/bd/sedimenting_cloud/run.py [--out DIR] [--threads T]
    python3 examples/bd/sedimenting_cloud/plot.py [--out DIR]
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
import _analysis as an  # noqa: E402

BASE = HERE.parent / "sedimentation.toml"
CASES = {  # name: (count, mobility)
    "hi_250": (250, "direct"),
    "hi_500": (500, "direct"),
    "hi_1000": (1000, "direct"),
    "hi_2000": (2000, "direct"),
    "fd_1000": (1000, "none"),
    "pse_2000": (2000, "pse"),  # PSE with open boundaries (no box): the same cloud as hi_2000
    "pse_20000": (20000, "pse"),
}


def main() -> int:
    args = an.script_args(__doc__, HERE)
    total = 0.0
    for name, (count, method) in CASES.items():
        cfg = an.derive_config(BASE, args.out / f"{name}.toml",
                               {"particles.count": count, "mobility.method": method})
        total += an.run_bd(cfg, args.out / name, threads=args.threads)
    print(f"done: {len(CASES)} runs in {total:.0f} s; now: python3 {HERE / 'plot.py'} --out {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
